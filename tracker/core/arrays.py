"""Which array library a hot-path function computes with: one implementation for numpy arrays and torch tensors
on any device (``--device cuda``), written against the Python array API standard (the likelihood's array path;
its CPU path is a compiled loop, :mod:`likelihoods.compiled_costs`).

numpy 2 implements the standard in its own namespace, so numpy arrays get numpy itself
(``array_api_compat``'s numpy wrappers measured 15% slower on the likelihood); torch tensors
get ``array_api_compat``'s torch namespace, which supplies the standard's names torch lacks
(``permute_dims``, ``astype``, ...).
"""
from __future__ import annotations

import re

import numpy as np
from array_api_compat import array_namespace, device, is_torch_array

from tracker.core.errors import InputError

__all__ = ["namespace", "device", "is_torch_array", "torch_device", "device_name"]


def namespace(x):
    """The array API namespace of ``x``: ``numpy`` for numpy arrays, else ``array_api_compat``'s."""
    return np if isinstance(x, np.ndarray) else array_namespace(x)


def device_name(name: str) -> str:
    """The canonical name of the torch device ``name`` (as ``str(torch_device(name))``), checked as
    :func:`torch_device` checks it; the CPU's names (``cpu``, ``cpu:N``) without importing torch."""
    if isinstance(name, str) and re.fullmatch(r"cpu(:(0|[1-9][0-9]*))?", name):
        return name
    return str(torch_device(name))


def is_cpu(name: str) -> bool:
    """Whether the device ``name`` (checked as :func:`device_name` checks it) is the CPU."""
    return device_name(name).split(":")[0] == "cpu"


def torch_device(name: str):
    """The torch device ``name`` (``cpu``, ``cuda``, ``cuda:N``), or an :class:`InputError` saying why it cannot
    be used (torch knows no such device, or no CUDA device is present)."""
    import torch

    try:
        dev = torch.device(name)
    except (RuntimeError, TypeError):
        raise InputError(f"unknown device {name!r}; use cpu, cuda or cuda:N") from None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise InputError(f"device {name!r} asked for, but torch finds no CUDA device on this machine")
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise InputError(f"device {name!r} asked for, but this machine has {torch.cuda.device_count()} "
                             "CUDA device(s)")
    elif dev.type != "cpu":
        raise InputError(f"device {name!r} is not supported; use cpu, cuda or cuda:N")
    if dev.type == "cuda" and dev.index is None:  # the same GPU from every thread (a bare "cuda" is per thread)
        dev = torch.device("cuda", torch.cuda.current_device())
    return dev
