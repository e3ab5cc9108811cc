"""relit.nn on numpy arrays: losses and Adam against numpy references, config errors as ValueError."""
import numpy as np
import pytest

import relit
import relit.nn


def test_l2_loss_and_gradient_match_numpy(device):
    rng = np.random.default_rng(0)
    p = rng.normal(size=(333, 3)).astype(np.float32)
    t = rng.normal(size=(333, 3)).astype(np.float32)
    value, grad = relit.nn.Loss({"type": "L2"}, device=device).evaluate(p, t, scale=3.0)
    d = p.astype(np.float64) - t
    assert value == pytest.approx(np.mean(d * d), rel=1e-5)
    np.testing.assert_allclose(grad, 3.0 * 2 * d / d.size, rtol=1e-5, atol=1e-9)


def test_tone_mapped_l2_matches_numpy(device):
    p = np.array([[0.0, 1.0, 4.0]], np.float32)
    t = np.array([[1.0, 1.0, 0.5]], np.float32)
    value, _ = relit.nn.Loss('{"otype": "ToneMappedL2"}', device=device).evaluate(p, t)
    m = lambda x: x / (1 + np.abs(x))  # noqa: E731
    assert value == pytest.approx(np.mean((m(p) - m(t)) ** 2), rel=1e-6)


def test_adam_first_step_moves_each_parameter_by_the_learning_rate(device):
    opt = relit.nn.Optimizer({"type": "Adam", "learning_rate": 0.1, "epsilon": 1e-12}, device=device)
    p = np.array([1.0, -2.0, 3.0], np.float32)
    g = np.array([0.5, -4.0, 1e-3], np.float32)
    new = opt.step(p, g)
    np.testing.assert_allclose(new, p - 0.1 * np.sign(g), rtol=1e-6)
    assert opt.step_count == 1
    assert opt.hyperparams["type"] == "Adam" and opt.hyperparams["beta1"] == pytest.approx(0.9)


def test_config_errors_are_value_errors_with_the_pointer(device):
    with pytest.raises(relit.ConfigError, match=r"/beta1: must be in \[0, 0.999999\], got 2") as e:
        relit.nn.Optimizer({"type": "Adam", "beta1": 2}, device=device)
    assert isinstance(e.value, ValueError) and e.value.pointer == "/beta1"
    with pytest.raises(ValueError, match="unknown loss type 'L7'; valid types: L2, RelativeL2, ToneMappedL2"):
        relit.nn.Loss({"type": "L7"}, device=device)
    with pytest.raises(ValueError, match="not valid JSON"):
        relit.nn.Loss("{type: L2", device=device)


def test_shape_errors(device):
    loss = relit.nn.Loss({"type": "L2"}, device=device)
    with pytest.raises(ValueError, match="different shapes"):
        loss.evaluate(np.zeros((4, 3), np.float32), np.zeros((5, 3), np.float32))


def test_config_reference_lists_components():
    text = relit.nn.config_reference()
    assert "### `Adam`" in text and "### `ToneMappedL2`" in text
