"""Butcher tableaux ``(A, b, c)`` of the explicit Runge–Kutta–Munthe-Kaas methods, by order.

Data shared by the integrators (:mod:`cartan.integrators.explicit`) and the compiled loops.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TABLEAUX"]

TABLEAUX: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {
    1: (np.array([[0.0]]), np.array([1.0]), np.array([0.0])),
    2: (np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([0.5, 0.5]), np.array([0.0, 1.0])),
    4: (
        np.array([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]], dtype=float),
        np.array([1, 2, 2, 1], dtype=float) / 6,
        np.array([0, 0.5, 0.5, 1.0]),
    ),
}
