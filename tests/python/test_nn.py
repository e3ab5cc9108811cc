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


def mlp_numpy(params, x, widths, out_act):
    """FullyFusedMLP in numpy (float64) from its documented layout: per layer a row-major [n_out][n_in + 1]
    block, the bias in the last column; ReLU hidden layers."""
    a, offset = x.astype(np.float64), 0
    for i, (n_in, n_out) in enumerate(zip(widths[:-1], widths[1:])):
        W = params[offset:offset + n_out * (n_in + 1)].astype(np.float64).reshape(n_out, n_in + 1)
        offset += n_out * (n_in + 1)
        a = a @ W[:, :-1].T + W[:, -1]
        if i < len(widths) - 2:
            a = np.maximum(a, 0)
    return out_act(a)


def test_network_forward_backward_and_params_match_numpy(device):
    net = relit.nn.Network({"type": "FullyFusedMLP", "n_neurons": 16, "n_hidden_layers": 2,
                            "output_activation": "Sigmoid"}, 5, 3, device=device, seed=3)
    widths = [5, 16, 16, 3]
    assert net.n_params == sum((i + 1) * o for i, o in zip(widths[:-1], widths[1:]))
    rng = np.random.default_rng(1)
    params = rng.normal(0, 0.5, size=net.n_params).astype(np.float32)
    net.params = params
    np.testing.assert_array_equal(net.params, params)
    x = rng.uniform(-1, 1, size=(77, 5)).astype(np.float32)
    sigmoid = lambda z: 1 / (1 + np.exp(-z))  # noqa: E731
    y = net.forward(x)
    np.testing.assert_allclose(y, mlp_numpy(params, x, widths, sigmoid), rtol=1e-5, atol=1e-6)
    # Backward of L = sum(w * y) against central differences of the numpy model.
    w = rng.normal(size=y.shape).astype(np.float32)
    d_x, d_params = net.backward(x, w)
    loss = lambda p, xx: np.sum(w * mlp_numpy(p, xx, widths, sigmoid))  # noqa: E731
    p64 = params.astype(np.float64)
    for i in rng.choice(net.n_params, 12, replace=False):
        e = np.zeros_like(p64)
        e[i] = 1e-6
        fd = (loss(p64 + e, x) - loss(p64 - e, x)) / 2e-6
        assert d_params[i] == pytest.approx(fd, rel=1e-3, abs=1e-4)
    e = np.zeros(x.shape)
    e[4, 2] = 1e-6
    fd = (loss(p64, x + e) - loss(p64, x - e)) / 2e-6
    assert d_x[4, 2] == pytest.approx(fd, rel=1e-3, abs=1e-4)
    assert net.hyperparams["n_neurons"] == 16 and net.type == "FullyFusedMLP"


def test_frequency_encoding_matches_numpy_and_its_gradient(device):
    enc = relit.nn.Encoding({"type": "Frequency", "n_frequencies": 3}, 2, device=device)
    x = np.array([[0.1, -0.7], [0.5, 0.25]], np.float32)
    y = enc.forward(x)
    expected = []
    for row in x.astype(np.float64):
        cols = []
        for v in row:
            for k in range(3):
                cols += [np.sin(2 ** k * np.pi * v), np.cos(2 ** k * np.pi * v)]
        expected.append(cols)
    np.testing.assert_allclose(y, expected, atol=2e-6)
    d_x, d_params = enc.backward(x, np.ones_like(y))
    assert d_params.size == 0
    v = x[0, 0].astype(np.float64)
    analytic = sum(2 ** k * np.pi * (np.cos(2 ** k * np.pi * v) - np.sin(2 ** k * np.pi * v)) for k in range(3))
    assert d_x[0, 0] == pytest.approx(analytic, rel=1e-4)


def test_hash_grid_parameters_get_set_and_shape_errors(device):
    enc = relit.nn.Encoding({"otype": "HashGrid", "n_levels": 2, "log2_hashmap_size": 10, "base_resolution": 4},
                            3, device=device, seed=1)
    p = enc.params
    assert p.shape == (enc.n_params,) and np.abs(p).max() <= 1e-4
    enc.params = np.zeros_like(p)
    assert not enc.forward(np.full((3, 3), 0.5, np.float32)).any()
    with pytest.raises(ValueError, match=r"input must have shape \(n, 3\)"):
        enc.forward(np.zeros((4, 2), np.float32))
    with pytest.raises(ValueError, match="expected .* parameters"):
        enc.params = np.zeros(3, np.float32)
