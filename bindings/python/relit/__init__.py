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
    build_features,
    devices,
    set_log_level,
)

__all__ = [
    "BuildError", "ClError", "ConfigError", "Device", "DeviceError", "DeviceInfo", "Error", "InvalidArgument",
    "IOError", "Program", "ProgramCheck", "__version__", "build_features", "devices", "set_log_level",
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

# Data parallelism (docs/scaling.md): under mpirun every Python process is a rank, and relit.Trainer,
# generate_dataset and write_report share their work out as the relit program does. MPI starts on import and
# ends at exit: cleanly after a script that ended normally; after an uncaught exception by ending the whole job,
# since the other ranks would otherwise wait for this one.
from ._core import ParallelError, parallel  # noqa: F401,E402

__all__ += ["ParallelError", "parallel"]

parallel.init()
if parallel.size() > 1:
    import atexit as _atexit
    import sys as _sys

    _failed = []
    _previous_hook = _sys.excepthook

    def _note_failure(kind, value, traceback):
        _failed.append(kind)
        _previous_hook(kind, value, traceback)

    _sys.excepthook = _note_failure
    _atexit.register(lambda: parallel.abort(1) if _failed else parallel.finalize())
