"""Choosing among equivalent Euler angle triples (radians).

A rotation has two Euler triples in any Tait–Bryan order (three distinct axes, as in BVH):
``(a, b, c)`` and ``(a + π, π − b, c + π)``, each up to multiples of 2π per angle. Converting
matrices back to Euler angles gives scipy's principal triple, which jumps at ±180° and can flip
branch from one frame to the next; exported curves then show spikes that a low-pass filter or an
animation tool turns into visible glitches. These helpers pick the triple nearest a reference
(:func:`euler_nearest`) or the previous frame (:func:`euler_continuous`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["euler_alternative", "euler_continuous", "euler_nearest"]

_TWO_PI = 2.0 * np.pi


def _check_order(order: str) -> None:
    if len(order) != 3 or len(set(order.upper())) != 3 or set(order.upper()) - set("XYZ"):
        raise ValueError(f"need a Tait-Bryan order of three distinct axes, got {order!r}")


def euler_alternative(euler: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) → the other triple of the same rotation: (a + π, π − b, c + π)."""
    _check_order(order)
    euler = np.asarray(euler, dtype=np.float64)
    return np.stack([euler[..., 0] + np.pi, np.pi - euler[..., 1], euler[..., 2] + np.pi], -1)


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles to [-π, π)."""
    return (x + np.pi) % _TWO_PI - np.pi


def euler_nearest(euler: np.ndarray, reference: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) Euler triples (radians) rewritten as the equivalent triple nearest
    ``reference`` (same shape): branch chosen by summed squared difference, then each angle
    shifted by the multiple of 2π that brings it closest to the reference angle."""
    euler = np.asarray(euler, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    candidates = np.stack([euler, euler_alternative(euler, order)])
    shifted = reference + _wrap(candidates - reference)
    cost = np.sum((shifted - reference) ** 2, axis=-1)
    pick = (cost[1] < cost[0])[..., None]
    return np.where(pick, shifted[1], shifted[0])


def euler_continuous(euler: np.ndarray, order: str) -> np.ndarray:
    """(F, ..., 3) Euler curves (radians, axis 0 = time) made continuous: frame 0 is kept, and
    every later frame takes the equivalent triple nearest the frame before it.

    Vectorised: the branch of each frame depends only on the branch of the frame before, a map
    on {0, 1} that is constant, the identity or a swap; the branch sequence follows from the
    last constant map and the parity of swaps since. Then angles are unwrapped over time.
    """
    euler = np.asarray(euler, dtype=np.float64)
    if euler.shape[0] < 2:
        return euler.copy()
    cand = np.stack([euler, euler_alternative(euler, order)])  # (2, F, ..., 3)
    prev, curr = cand[:, :-1], cand[:, 1:]
    # dist[p, s] over (F-1, ...): wrapped distance from branch p at t-1 to branch s at t.
    dist = np.stack(
        [np.stack([np.sum(_wrap(curr[s] - prev[p]) ** 2, axis=-1) for s in (0, 1)]) for p in (0, 1)]
    )
    next0 = (dist[0, 1] < dist[0, 0]).astype(np.int8)  # branch at t when t-1 used branch 0
    next1 = (dist[1, 1] < dist[1, 0]).astype(np.int8)  # ... when t-1 used branch 1
    is_const = next0 == next1
    is_swap = (next0 == 1) & (next1 == 0)
    n = euler.shape[0]
    lead = (1,) + next0.shape[1:]
    is_const = np.concatenate([np.ones(lead, bool), is_const])  # frame 0: branch 0
    const_val = np.concatenate([np.zeros(lead, np.int8), next0])
    swaps = np.cumsum(np.concatenate([np.zeros(lead, np.int64), is_swap]), axis=0)
    t = np.arange(n).reshape((n,) + (1,) * (euler.ndim - 2))
    last_const = np.maximum.accumulate(np.where(is_const, t, 0), axis=0)
    base = np.take_along_axis(const_val, last_const, axis=0)
    parity = (swaps - np.take_along_axis(swaps, last_const, axis=0)) % 2
    branch = (base ^ parity.astype(np.int8)).astype(bool)
    chosen = np.where(branch[..., None], cand[1], cand[0])
    chosen[0] = euler[0]
    return np.unwrap(chosen, axis=0)
