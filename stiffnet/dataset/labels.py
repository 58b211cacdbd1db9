"""Stiffness classes from beta and the impact regime."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def beta_class_index(beta: np.ndarray, edges: Sequence[float]) -> np.ndarray:
    """Index (1-based) of the beta class for each value; ``edges`` are the class bounds.

    Classes are ``[edges[i], edges[i+1])``, the last one closed on the right. Values
    outside the edges are clipped to the first or last class.
    """
    edges = np.asarray(edges, float)
    idx = np.searchsorted(edges, beta, side="right")
    return np.clip(idx, 1, edges.size - 1)


def window_labels(beta: np.ndarray, has_contact: np.ndarray, edges: Sequence[float]) -> np.ndarray:
    """Class index per window: 0 for no contact in the window, else the beta class."""
    return np.where(has_contact, beta_class_index(beta, edges), 0)
