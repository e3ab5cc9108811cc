"""relit.write_report / relit.contact_sheet: views as dicts or objects, metrics given or computed, files parsed
back, panels checked against numpy, clear errors for bad input."""
import json
import math
import os
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

import relit
import relit.metrics

INFERNO_0 = (0.001462, 0.000466, 0.013866)  # sRGB at the bottom of the error map
INFERNO_1 = (0.988362, 0.998364, 0.644924)  # and at the top


def srgb(x):
    x = np.clip(x, 0.0, 1.0).astype(np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def images(seed, h=16, w=12, noise=0.05):
    rng = np.random.default_rng(seed)
    ref = rng.uniform(0.0, 1.0, size=(h, w, 3)).astype(np.float32)
    return (ref + rng.normal(0, noise, size=ref.shape)).astype(np.float32), ref


def test_write_report_computes_missing_metrics(device, tmp_path):
    views = []
    for i in range(3):
        pred, ref = images(i)
        views.append({"split": "test" if i < 2 else "test_light", "name": f"r_{i:03d}", "prediction": pred,
                      "reference": ref})
    lines = relit.write_report(tmp_path / "eval", views, meta={"method": "ours", "steps": 12}, device=device)
    out = tmp_path / "eval"
    report = json.loads((out / "metrics.json").read_text())
    expected = [relit.metrics.compare(v["prediction"], v["reference"], device=device) for v in views]
    for got, want in zip(report["views"], expected):
        assert got["psnr"] == pytest.approx(want["psnr"], rel=1e-12)
        assert got["ssim"] == pytest.approx(want["ssim"], rel=1e-12)
        assert got["flip"] == pytest.approx(want["flip"], rel=1e-12) and 0 < got["flip"] < 1
    assert list(report["splits"]) == ["test", "test_light"]
    assert report["splits"]["test"]["psnr"] == pytest.approx((expected[0]["psnr"] + expected[1]["psnr"]) / 2)
    assert report["mean"]["n_views"] == 3
    assert report["meta"] == {"method": "ours", "steps": 12}
    # The last two lines are what scripts parse.
    last = lines.splitlines()[-2:]
    assert last[0].startswith("PSNR ") and last[1].startswith("SSIM ")
    assert float(last[0].split()[1]) == pytest.approx(report["mean"]["psnr"], abs=1e-4)
    assert float(last[1].split()[1]) == pytest.approx(report["mean"]["ssim"], abs=1e-4)
    assert report["mean"]["flip"] == pytest.approx(sum(m["flip"] for m in expected) / 3)
    assert "| test | 2 |" in (out / "metrics.md").read_text() and "| FLIP |" in (out / "metrics.md").read_text()
    assert " FLIP " in lines.splitlines()[0]
    for split in ("test", "test_light"):
        assert (out / f"contact_sheet_{split}.png").exists()
    assert not (out / "test").exists()


def test_objects_with_given_metrics_and_predictions_on_disk(tmp_path):
    pred, ref = images(7, h=4, w=5)
    views = [SimpleNamespace(split="test", name="a", prediction=pred, reference=ref, psnr=30.0, ssim=0.9, mse=1e-3),
             SimpleNamespace(split="test", name="b", prediction=pred.astype(np.float64), reference=ref,
                             metrics={"psnr": 20.0, "ssim": 0.7, "mse": 1e-2})]
    lines = relit.write_report(str(tmp_path), views, write_predictions=True, write_exr=True)
    assert lines == ("test: PSNR 25.00 dB  SSIM 0.8000 (2 views)\nPSNR 25.0000  (mean over the 2 test views)\n"
                     "SSIM 0.8000  (mean over the 2 test views)\n")
    report = json.loads((tmp_path / "metrics.json").read_text())
    assert report["mean"]["mse"] == pytest.approx(5.5e-3)
    assert report["mean"]["flip"] is None  # given metrics without 'flip': not computed
    png = np.asarray(Image.open(tmp_path / "test" / "a.png").convert("RGB"), np.float64) / 255
    assert png.shape == (4, 5, 3)
    assert np.abs(png - srgb(pred)).max() <= 0.5 / 255 + 1e-6
    assert (tmp_path / "test" / "b.exr").exists()


def test_contact_sheet_panels():
    pred, ref = images(3, h=6, w=5, noise=0.3)
    pred[0, 0] = [2.0, -1.0, 0.5]  # out of range: shown clamped
    same = {"name": "same", "prediction": ref, "reference": ref}
    off = {"name": "off", "prediction": np.ones_like(ref), "reference": np.zeros_like(ref)}
    sheet = relit.contact_sheet([{"name": "x", "prediction": pred, "reference": ref}, same, off], labels=False)
    g, h, w = 4, 6, 5
    assert sheet.dtype == np.float32 and sheet.shape == (3 * (h + g) + g, 3 * w + 4 * g, 3)
    np.testing.assert_allclose(sheet[g:g + h, g:g + w], np.clip(pred, 0, 1))           # prediction
    np.testing.assert_allclose(sheet[g:g + h, 2 * g + w:2 * g + 2 * w], ref)            # | reference
    err = sheet[g:g + h, 3 * g + 2 * w:3 * g + 3 * w]                                    # | error
    mad = np.abs(srgb(pred) - srgb(ref)).mean(axis=2)
    luminance = err @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    # The error panel is ordered like the error (inferno's luminance rises with it).
    flat_mad, flat_b = mad.ravel(), luminance.ravel()
    order = np.argsort(flat_mad)
    assert np.all(np.diff(flat_b[order]) >= -1e-4)
    # No error → the map's zero colour; error ≥ 0.25 → its top.
    y1, y2 = 2 * g + h, 3 * g + 2 * h
    np.testing.assert_allclose(srgb(sheet[y1:y1 + h, 3 * g + 2 * w:3 * g + 3 * w]), np.broadcast_to(INFERNO_0, (h, w, 3)),
                               atol=1e-5)
    np.testing.assert_allclose(srgb(sheet[y2:y2 + h, 3 * g + 2 * w:3 * g + 3 * w]), np.broadcast_to(INFERNO_1, (h, w, 3)),
                               atol=1e-5)
    # srgb=True: the display values; max_rows caps the rows.
    np.testing.assert_allclose(relit.contact_sheet([same], srgb=True), srgb(relit.contact_sheet([same])), atol=1e-5)
    assert relit.contact_sheet([same, off, same], max_rows=2, labels=False).shape[0] == 2 * (h + g) + g
    # Labels: a title band and a caption band per row, the colour bar; cells at least 72 pixels wide.
    band, bar = 15, 8
    labelled = relit.contact_sheet([same, off])
    assert labelled.shape == (g + band + 2 * (h + band + g) + bar + band + g, 3 * 72 + 4 * g, 3)
    assert labelled[g:g + band].max() > 0.5  # the titles


def test_bad_views_are_value_errors_naming_the_view(tmp_path):
    pred, ref = images(1, h=4, w=4)
    bad = pred.copy()
    bad[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"test/b.*NaN at pixel \(x 1, y 2\)"):
        relit.write_report(tmp_path, [{"name": "a", "prediction": pred, "reference": ref},
                                      {"name": "b", "prediction": bad, "reference": ref}])
    assert not (tmp_path / "metrics.json").exists()
    with pytest.raises(ValueError, match=r"views\[0\].*no 'reference'"):
        relit.contact_sheet([{"name": "a", "prediction": pred}])
    with pytest.raises(ValueError, match="same shape"):
        relit.contact_sheet([{"prediction": pred, "reference": ref[:3]}])
    with pytest.raises(ValueError, match=r"\(height, width, 3\)"):
        relit.contact_sheet([{"prediction": pred[..., 0], "reference": ref[..., 0]}])
    with pytest.raises(ValueError, match="psnr, ssim and mse"):
        relit.write_report(tmp_path, [{"prediction": pred, "reference": ref, "psnr": 20.0}])
    with pytest.raises(ValueError, match="no views"):
        relit.write_report(tmp_path, [])
    with pytest.raises(ValueError, match="meta must be a JSON object"):
        relit.write_report(tmp_path, [{"prediction": pred, "reference": ref, "psnr": 1.0, "ssim": 0.1, "mse": 0.5}],
                           meta=[1, 2])
    assert os.listdir(tmp_path) == []


def test_perfect_view_has_null_psnr(device, tmp_path):
    _, ref = images(5)
    lines = relit.write_report(tmp_path, [{"prediction": ref, "reference": ref}], device=device)
    report = json.loads((tmp_path / "metrics.json").read_text())
    assert report["views"][0]["psnr"] is None and report["mean"]["psnr"] is None
    assert math.isinf(float(lines.splitlines()[-2].split()[1]))


def test_cli_eval_compares_two_folders_of_images(tmp_path):
    """relit eval --predictions DIR --references DIR: another renderer's images (here a noisier rendering of the
    same views) against a dataset, the same report; identical folders score +inf (null); a missing prediction is
    an error naming it."""
    from conftest import run_python

    def generate(out, spp):
        r = run_python(["-m", "relit", "generate", "--scene", "cloud", "--scene-resolution", "16", "--resolution", "16",
                        "--train", "1", "--val", "0", "--test", "2", "--spp", str(spp), "--out", str(out)])
        assert r.returncode == 0, r.stderr

    generate(tmp_path / "ref", 16)
    generate(tmp_path / "pred", 1)
    r = run_python(["-m", "relit", "eval", "--predictions", str(tmp_path / "pred"), "--references", str(tmp_path / "ref"),
                    "--out", str(tmp_path / "report")])
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "report" / "metrics.json").read_text())
    assert [(v["split"], v["name"]) for v in report["views"]] == [("test", "r_000"), ("test", "r_001"), ("train", "r_000")]
    for v in report["views"]:
        assert 10 < v["psnr"] < 80 and v["object"]["pixels"] > 0  # the EXRs' alpha gives the object
        assert 0 <= v["object"]["clipped"] <= 1 and v["object"]["rel_mse"] > 0
        assert 0 < v["flip"] < 1 and 0 < v["object"]["flip"] < 1
    assert "object: PSNR" in r.stdout and (tmp_path / "report" / "contact_sheet_test.png").exists()

    # --split keeps the dataset's test views (predictions of the test views alone need no training views).
    os.remove(tmp_path / "pred" / "train" / "r_000.exr")
    os.remove(tmp_path / "pred" / "train" / "r_000.png")
    test_only = run_python(["-m", "relit", "eval", "--predictions", str(tmp_path / "pred"), "--references",
                            str(tmp_path / "ref"), "--split", "test", "--out", str(tmp_path / "test_only")])
    assert test_only.returncode == 0, test_only.stderr
    views = json.loads((tmp_path / "test_only" / "metrics.json").read_text())["views"]
    assert [(v["split"], v["name"]) for v in views] == [("test", "r_000"), ("test", "r_001")]
    assert views == report["views"][:2]
    nosplit = run_python(["-m", "relit", "eval", "--predictions", str(tmp_path / "pred"), "--references",
                          str(tmp_path / "ref"), "--split", "test_light", "--out", str(tmp_path / "nosplit")])
    assert nosplit.returncode != 0 and "'test_light'" in nosplit.stderr
    assert not (tmp_path / "nosplit").exists()

    same = run_python(["-m", "relit", "eval", "--predictions", str(tmp_path / "ref"), "--references", str(tmp_path / "ref"),
                       "--out", str(tmp_path / "same")])
    assert same.returncode == 0, same.stderr
    assert json.loads((tmp_path / "same" / "metrics.json").read_text())["mean"]["psnr"] is None  # +inf

    os.remove(tmp_path / "pred" / "test" / "r_001.exr")
    os.remove(tmp_path / "pred" / "test" / "r_001.png")
    bad = run_python(["-m", "relit", "eval", "--predictions", str(tmp_path / "pred"), "--references", str(tmp_path / "ref"),
                      "--out", str(tmp_path / "bad")])
    assert bad.returncode != 0 and "test/r_001" in bad.stderr and "no prediction" in bad.stderr
    assert not (tmp_path / "bad").exists()
