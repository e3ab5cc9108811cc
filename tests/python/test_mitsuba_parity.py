"""The reference path tracer against Mitsuba 3's volumetric path tracer (`volpath`, scalar_rgb variant): the same
heterogeneous medium, camera and point light rendered by both, compared pixel by pixel and in the mean with z-tests
on both renderers' Monte Carlo noise. docs/reliability.md ("Independent answers") lists how each relit convention maps
onto Mitsuba's."""
import math

import mitsuba as mi  # scripts/setup.sh installs it into the venv; missing, the test fails (never skips)
import numpy as np
import pytest

import relit

mi.set_variant("scalar_rgb")

# The scene: relit's procedural cloud on a 16^3 grid, a grey albedo below 1 (Russian roulette and ratio-tracking
# roulette both fire), a camera at distance 4 and a point light in front of the cloud or behind it.
SPP = 1024
SIZE = 16
FOV = 0.45  # camera_angle_x, radians
EYE = (0.3, -4.0, 0.6)
DENSITY_SCALE = 20.0
ALBEDO = 0.9
INTENSITY = 30.0  # W/sr
LIGHTS = {"front-lit": (2.0, -3.0, 2.5), "back-lit": (-0.8, 3.5, 1.0)}


def write_vol(path, density):
    """Mitsuba's binary grid format: 'VOL', version 3, encoding 1 (float32), x/y/z resolution, channels, a bounding
    box (unused: the volume's to_world places it), then the values with x fastest, as relit's Grid."""
    nz, ny, nx = density.shape
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(np.array([1, nx, ny, nz, 1], dtype="<i4").tobytes())
        f.write(np.array([-1, -1, -1, 1, 1, 1], dtype="<f4").tobytes())
        f.write(np.ascontiguousarray(density, dtype="<f4").tobytes())


def mitsuba_scene(vol_file, g, light):
    T = mi.ScalarTransform4f
    return mi.load_dict({
        "type": "scene",
        # `moment` wraps volpath and adds each pixel's second moment, for the per-pixel variance.
        "integrator": {"type": "moment", "nested": {"type": "volpath", "max_depth": -1}},
        "sensor": {
            "type": "perspective",
            "fov_axis": "x",
            "fov": math.degrees(FOV),
            "to_world": T().look_at(origin=EYE, target=(0, 0, 0), up=(0, 0, 1)),
            "sampler": {"type": "independent", "sample_count": SPP},
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
        },
        # Mitsuba's cube is [-1, 1]^3, relit's box; a null BSDF makes its surface an index-matched boundary.
        "medium_box": {
            "type": "cube",
            "bsdf": {"type": "null"},
            "interior": {
                "type": "heterogeneous",
                "albedo": ALBEDO,
                "scale": DENSITY_SCALE,
                # The grid's unit cube mapped onto [-1, 1]^3; voxel-centred trilinear lookups clamped at the edges,
                # as relit's.
                "sigma_t": {"type": "gridvolume", "filename": str(vol_file),
                            "to_world": T().translate((-1, -1, -1)).scale(2)},
                "phase": {"type": "hg", "g": g},
            },
        },
        "light": {"type": "point", "position": light, "intensity": INTENSITY},
    })


def render_mitsuba(scene, seed):
    """Mean and variance of the mean per pixel (grey: the red channel and the nested integrator's Y moment)."""
    image = np.array(mi.render(scene, spp=SPP, seed=seed))
    moments = dict(scene.sensors()[0].film().bitmap().split())
    mean = image[..., 0].astype(np.float64)
    m1 = np.array(moments["nested"])[..., 1].astype(np.float64)
    m2 = np.array(moments["m2_nested"])[..., 1].astype(np.float64)
    assert np.allclose(m1, mean, rtol=1e-5, atol=1e-7), "Mitsuba's moment channels are not the image's"
    return mean, np.maximum(m2 - m1 * m1, 0) / (SPP - 1)


@pytest.mark.parametrize("g", [0.0, 0.7])
@pytest.mark.parametrize("lighting", ["front-lit", "back-lit"])
def test_path_tracer_matches_mitsuba_volpath(device, tmp_path, g, lighting):
    light = LIGHTS[lighting]
    scene = relit.Scene.from_json({"medium": {"source": {"type": "cloud", "resolution": 16, "seed": 1},
                                              "density_scale": DENSITY_SCALE, "albedo": ALBEDO, "g": g}})
    density = scene.medium_density
    assert density.shape == (16, 16, 16) and density.max() > 0.5 and (density == 0).mean() > 0.2, "heterogeneous"
    write_vol(tmp_path / "density.vol", density)

    camera = relit.Camera.look_at(EYE, (0, 0, 0), (0, 0, 1), FOV, SIZE, SIZE)
    img, var = relit.render_reference(scene, camera, [relit.PointLight(light, INTENSITY)], spp=SPP, seed=11,
                                      device=device, with_variance=True)
    assert np.array_equal(img[..., 0], img[..., 1]) and np.array_equal(img[..., 0], img[..., 2]), "grey medium"
    relit_mean = img[..., 0].astype(np.float64)
    relit_var = var[..., 0].astype(np.float64) / SPP
    mitsuba_mean, mitsuba_var = render_mitsuba(mitsuba_scene(tmp_path / "density.vol", g, light), seed=5)

    se2 = relit_var + mitsuba_var
    lit = se2 > 0
    assert lit.mean() > 0.3, "the medium must cover a good part of the image for the test to mean anything"
    # Where neither renderer saw any light (rays that miss the medium) both must be exactly black.
    assert not relit_mean[~lit].any() and not mitsuba_mean[~lit].any()
    z = (relit_mean - mitsuba_mean)[lit] / np.sqrt(se2[lit])
    z_mean = (relit_mean.sum() - mitsuba_mean.sum()) / math.sqrt(se2.sum())
    report = (f"g {g}, {lighting}: image mean relit {relit_mean.mean():.6f}, Mitsuba {mitsuba_mean.mean():.6f}, "
              f"z {z_mean:.2f}; {lit.sum()} pixels, worst |z| {np.abs(z).max():.2f}, mean z^2 {np.mean(z * z):.3f}")
    print(report)
    assert abs(z_mean) < 4, report
    assert np.abs(z).max() < 5, report
    # The spread of the z-scores: about 1 when the two images agree and the variances are right (loose bounds for
    # the heavy tails of path-traced pixels and the sampling error of the variances).
    assert 0.6 < np.mean(z * z) < 1.6, report
