"""relit.nn: encodings, networks, losses and optimisers callable on numpy arrays.

    import numpy as np, relit.nn
    loss = relit.nn.Loss({"type": "L2"})
    value, grad = loss.evaluate(np.ones((4, 3), np.float32), np.zeros((4, 3), np.float32))
"""
from ._core import nn as _nn

Encoding = _nn.Encoding
Network = _nn.Network
Loss = _nn.Loss
Optimizer = _nn.Optimizer
config_reference = _nn.config_reference

__all__ = ["Encoding", "Loss", "Network", "Optimizer", "config_reference"]
