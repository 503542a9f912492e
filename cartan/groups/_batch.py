"""Broadcasting and flattening glue between vectorised arrays and per-point kernels.

A numba batch kernel has the form ``kernel(a_flat, b_flat, ..., out_flat)``: every input
is a C-contiguous array of shape ``(P, *core_shape)`` and the output ``(P, *out_core)`` is
filled in place.  :func:`run_kernel` broadcasts the leading (batch) axes of the inputs
against each other, flattens them to ``P`` points, calls the kernel and restores them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np


def leading_shape(arrays: Sequence[np.ndarray], core_ndims: Sequence[int]) -> tuple[int, ...]:
    """Broadcast shape of the batch axes of ``arrays`` (each has ``core_ndims[i]`` core axes)."""
    return np.broadcast_shapes(*(a.shape[: a.ndim - k] for a, k in zip(arrays, core_ndims)))


def run_kernel(
    kernel: Callable[..., None],
    out_core: tuple[int, ...],
    arrays: Sequence[np.ndarray],
    core_ndims: Sequence[int],
) -> np.ndarray:
    """Call a batch kernel on broadcast, flattened inputs and return the reshaped output.

    Parameters
    ----------
    kernel
        numba function ``kernel(*flat_inputs, out)``.
    out_core
        Core shape of one output point, e.g. ``(4, 4)``.
    arrays
        Inputs, float64, each of shape ``[..., *core]``.
    core_ndims
        Number of core axes of each input.

    Returns
    -------
    numpy.ndarray
        Shape ``[..., *out_core]`` with the broadcast batch shape in front.
    """
    first, k0 = arrays[0], core_ndims[0]
    lead = first.shape[: first.ndim - k0]
    if all(a.shape[: a.ndim - k] == lead and a.flags.c_contiguous for a, k in zip(arrays, core_ndims)):
        # the common case: same batch shape, contiguous — reshape views, no broadcast copies
        npts = math.prod(lead)
        flat = [a.reshape((npts, *a.shape[a.ndim - k:])) for a, k in zip(arrays, core_ndims)]
    else:
        lead = leading_shape(arrays, core_ndims)
        npts = math.prod(lead)
        flat = []
        for a, k in zip(arrays, core_ndims):
            core = a.shape[a.ndim - k :]
            flat.append(np.ascontiguousarray(np.broadcast_to(a, lead + core).reshape((npts, *core))))
    out = np.empty((npts, *out_core))
    kernel(*flat, out)
    return out.reshape(lead + tuple(out_core))


#: the operations a group module may provide batch kernels for, as ``_<op>_batch``
KERNEL_OPS = ("hat", "vee", "compose", "inverse", "act", "exp", "log", "Ad", "ad", "bracket", "dexp",
              "dexp_inv", "E")


def kernel_table(namespace: dict) -> dict[str, Callable[..., None]]:
    """``{op: kernel}`` for every ``_<op>_batch`` function defined in a module's namespace
    (pass ``globals()``); the result is a group class's ``_kernels`` table."""
    return {op: namespace[f"_{op}_batch"] for op in KERNEL_OPS if f"_{op}_batch" in namespace}
