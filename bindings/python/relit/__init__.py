"""relit: neural relightable participating media on OpenCL.

    import relit
    relit.devices()                    # every OpenCL device
    dev = relit.Device.select("cpu")   # or RELIT_DEVICE=..., as pyopencl's PYOPENCL_CTX
"""
from . import metrics, nn  # noqa: F401
from ._core import (  # noqa: F401
    BuildError,
    ClError,
    ConfigError,
    Device,
    DeviceError,
    DeviceInfo,
    Error,
    InvalidArgument,
    IOError,
    Program,
    ProgramCheck,
    __version__,
    devices,
    set_log_level,
)

__all__ = [
    "BuildError", "ClError", "ConfigError", "Device", "DeviceError", "DeviceInfo", "Error", "InvalidArgument",
    "IOError", "Program", "ProgramCheck", "__version__", "devices", "set_log_level",
]

# Scenes, the reference path tracer and dataset generation.
from ._core import Camera, PointLight, Progress, Scene, generate_dataset, render_reference  # noqa: F401,E402

__all__ += ["Camera", "PointLight", "Progress", "Scene", "generate_dataset", "render_reference"]

# The method: training and relighting.
from ._core import EnvironmentLight, Model, Trainer, TrainStats, methods, preset, presets  # noqa: F401,E402

__all__ += ["EnvironmentLight", "Model", "Trainer", "TrainStats", "methods", "preset", "presets"]

# Interop: the learned medium for other tools (docs/interop.md).
from ._core import export_mitsuba, export_vdb, render_orbit, render_path, sample_medium  # noqa: F401,E402

__all__ += ["export_mitsuba", "export_vdb", "render_orbit", "render_path", "sample_medium"]

# Evaluation reports: metrics.json / metrics.md / contact sheets from predictions and references.
from ._core import contact_sheet, write_report  # noqa: F401,E402

__all__ += ["contact_sheet", "write_report"]
