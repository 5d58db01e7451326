"""Axis-angle → quaternion, rotation matrix and Euler angles in one compiled pass.

The same formulas as scipy's ``Rotation`` (``from_rotvec``, ``as_quat(canonical=True)``,
``as_matrix``, ``as_euler`` by the quaternion method of Bernardes & Viollet 2022, singular
frames with the third angle set to 0), evaluated per rotation in float64 inside one numba loop
instead of a dozen array passes: the motion representations of a million frames of 24 joints
cost a fraction of a CPU-second. The compiled code is cached on disk (``cache=True``), so it is
built once per machine, not once per process. ``quat_sign_continuous_spans`` makes quaternions
sign-continuous within each sequence of a batch in one pass.

Agreement with scipy (tests/compute/test_rotation_kernels.py): quaternions and matrices to 1e-15,
Euler angles to 1e-12 rad away from gimbal lock; at gimbal lock both give the same rotation.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "euler_order_params",
    "quat_sign_continuous_spans",
    "rotation_representations",
    "rotations_from_axis_angle",
    "span_links",
]

_AXIS = {"x": 0, "y": 1, "z": 2}


def euler_order_params(order: str) -> np.ndarray:
    """(6,) int64 [i, j, k, symmetric, sign, extrinsic] of a scipy Euler order ("XYZ" intrinsic,
    "xyz" extrinsic, proper orders like "ZXZ" too), as scipy's ``as_euler`` derives them."""
    if len(order) != 3 or not (order.isupper() or order.islower()):
        raise ValueError(f"an Euler order is three of x, y, z (all upper or all lower): {order!r}")
    if any(a not in "xyz" for a in order.lower()) or order[0] == order[1] or order[1] == order[2]:
        raise ValueError(f"not an Euler order: {order!r}")
    extrinsic = order.islower()
    axes = [_AXIS[a] for a in order.lower()]
    if not extrinsic:
        axes = axes[::-1]
    i, j, k = axes
    symmetric = i == k
    if symmetric:
        k = 3 - i - j
    sign = (i - j) * (j - k) * (k - i) // 2
    return np.array([i, j, k, int(symmetric), sign, int(extrinsic)], dtype=np.int64)


@numba.njit(cache=True, nogil=True, inline="always")
def _wrap(angle: float) -> float:
    """Into [−π, π): the angles here lie within (−3π, 3π), so one step of 2π suffices."""
    if angle >= math.pi:
        return angle - 2.0 * math.pi
    if angle < -math.pi:
        return angle + 2.0 * math.pi
    return angle


@numba.njit(cache=True, nogil=True)
def _convert(aa, params, want_quat, want_rotmat, want_euler, quat, rotmat, euler):  # noqa: ANN001
    """float64 outputs, no sign continuity: :func:`rotations_from_axis_angle`."""
    empty6 = np.empty((0, 0, 0), dtype=quat.dtype)
    links = np.zeros(0, dtype=np.int8)
    _convert_all(
        aa, params, links, want_quat, want_rotmat, want_euler, False, False,
        quat, rotmat, euler, empty6, empty6,
    )  # fmt: skip
    return 0


@numba.njit(cache=True, nogil=True)
def _convert_all(  # noqa: ANN001, PLR0913
    aa, params, links, want_quat, want_rotmat, want_euler, want_6d, want_6d_rows,
    quat, rotmat, euler, rot6d, rot6d_rows,
):  # fmt: skip
    """Every representation of every rotation in one pass, each value computed in float64 and
    written into the output arrays' own dtype (float32 for the stores: the one rounding a later
    ``astype`` would do). With ``links`` (F,) non-empty, quaternions are made sign-continuous
    on the fly: ``links[f]`` is 1 where frame f continues frame f − 1 of the same sequence; the
    raw (canonical, float64) neighbours' dot decides a flip and flips accumulate, exactly as
    :func:`_sign_spans` does on float64 quaternions."""
    n_frames, n_joints = aa.shape[0], aa.shape[1]
    q = np.empty(4)
    signs = links.shape[0] > 0
    prev = np.zeros((n_joints, 4))
    flipped = np.zeros(n_joints, dtype=np.bool_)
    for f in range(n_frames):
        linked = signs and links[f] == 1
        for jj in range(n_joints):
            vx = np.float64(aa[f, jj, 0])
            vy = np.float64(aa[f, jj, 1])
            vz = np.float64(aa[f, jj, 2])
            angle = math.sqrt(vx * vx + vy * vy + vz * vz)
            if angle <= 1e-3:
                a2 = angle * angle
                scale = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
            else:
                scale = math.sin(angle / 2.0) / angle
            x, y, z, w = vx * scale, vy * scale, vz * scale, math.cos(angle / 2.0)
            if want_quat:
                # canonical: w > 0, or w == 0 and the first non-zero of x, y, z positive
                flip = w < 0 or (w == 0 and (x < 0 or (x == 0 and (y < 0 or (y == 0 and z < 0)))))
                s = -1.0 if flip else 1.0
                r0, r1, r2, r3 = s * w, s * x, s * y, s * z
                if signs:
                    if linked:
                        p = prev[jj]
                        if r0 * p[0] + r1 * p[1] + r2 * p[2] + r3 * p[3] < 0:
                            flipped[jj] = not flipped[jj]
                    else:
                        flipped[jj] = False
                    prev[jj, 0], prev[jj, 1], prev[jj, 2], prev[jj, 3] = r0, r1, r2, r3
                    if flipped[jj]:
                        r0, r1, r2, r3 = -r0, -r1, -r2, -r3
                quat[f, jj, 0] = r0
                quat[f, jj, 1] = r1
                quat[f, jj, 2] = r2
                quat[f, jj, 3] = r3
            if want_rotmat or want_6d or want_6d_rows:
                x2, y2, z2, w2 = x * x, y * y, z * z, w * w
                xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
                m00 = x2 - y2 - z2 + w2
                m01 = 2 * (xy - zw)
                m02 = 2 * (xz + yw)
                m10 = 2 * (xy + zw)
                m11 = -x2 + y2 - z2 + w2
                m12 = 2 * (yz - xw)
                m20 = 2 * (xz - yw)
                m21 = 2 * (yz + xw)
                m22 = -x2 - y2 + z2 + w2
                if want_rotmat:
                    rotmat[f, jj, 0, 0] = m00
                    rotmat[f, jj, 0, 1] = m01
                    rotmat[f, jj, 0, 2] = m02
                    rotmat[f, jj, 1, 0] = m10
                    rotmat[f, jj, 1, 1] = m11
                    rotmat[f, jj, 1, 2] = m12
                    rotmat[f, jj, 2, 0] = m20
                    rotmat[f, jj, 2, 1] = m21
                    rotmat[f, jj, 2, 2] = m22
                if want_6d:  # Zhou's columns: (r00, r10, r20, r01, r11, r21)
                    rot6d[f, jj, 0] = m00
                    rot6d[f, jj, 1] = m10
                    rot6d[f, jj, 2] = m20
                    rot6d[f, jj, 3] = m01
                    rot6d[f, jj, 4] = m11
                    rot6d[f, jj, 5] = m21
                if want_6d_rows:  # rows: (r00, r01, r02, r10, r11, r12)
                    rot6d_rows[f, jj, 0] = m00
                    rot6d_rows[f, jj, 1] = m01
                    rot6d_rows[f, jj, 2] = m02
                    rot6d_rows[f, jj, 3] = m10
                    rot6d_rows[f, jj, 4] = m11
                    rot6d_rows[f, jj, 5] = m12
            if want_euler:
                i, j, k = params[jj, 0], params[jj, 1], params[jj, 2]
                symmetric, sign, extrinsic = params[jj, 3], params[jj, 4], params[jj, 5]
                q[0], q[1], q[2], q[3] = x, y, z, w
                if symmetric:
                    a, b, c, d = q[3], q[i], q[j], q[k] * sign
                else:
                    a = q[3] - q[j]
                    b = q[i] + q[k] * sign
                    c = q[j] + q[3]
                    d = q[k] * sign - q[i]
                half_sum = math.atan2(b, a)
                half_diff = math.atan2(d, c)
                second = 2.0 * math.atan2(math.sqrt(c * c + d * d), math.sqrt(a * a + b * b))
                case1 = abs(second) <= 1e-7
                case2 = abs(second - math.pi) <= 1e-7
                # angles e0, e1 = second, e2; first and third are e0/e2 (e2/e0 intrinsic)
                e0 = 2.0 * half_sum if case1 else 2.0 * half_diff * (-1.0 if extrinsic else 1.0)
                e1 = second
                e2 = 0.0
                if not (case1 or case2):
                    if extrinsic:
                        e0 = half_sum - half_diff
                    else:
                        e2 = half_sum - half_diff
                    third = half_sum + half_diff
                else:
                    third = e2 if extrinsic else e0
                if not symmetric:
                    third = third * sign
                    e1 = e1 - math.pi / 2.0
                if extrinsic:
                    e2 = third
                else:
                    e0 = third
                euler[f, jj, 0] = _wrap(e0)
                euler[f, jj, 1] = _wrap(e1)
                euler[f, jj, 2] = _wrap(e2)
    return 0


def rotations_from_axis_angle(
    axis_angle: np.ndarray,
    *,
    quat: bool = True,
    rotmat: bool = True,
    euler_order: str | list[str] | None = "XYZ",
) -> dict[str, np.ndarray]:
    """(F, J, 3) axis-angle (radians) → ``quat`` (F, J, 4) wxyz canonical (w ≥ 0), ``rotmat``
    (F, J, 3, 3), ``euler`` (F, J, 3) radians in ``euler_order`` (one scipy order, or one per
    joint; None: no Euler angles), all float64."""
    aa = np.ascontiguousarray(axis_angle)
    if aa.ndim != 3 or aa.shape[-1] != 3:
        raise ValueError(f"need axis-angle (F, J, 3), got {aa.shape}")
    if aa.dtype not in (np.float32, np.float64):
        aa = aa.astype(np.float64)
    n_frames, n_joints = aa.shape[:2]
    params = _euler_params(euler_order, n_joints)
    empty = np.empty((0, 0, 0))
    out_q = np.empty((n_frames, n_joints, 4)) if quat else empty
    out_r = np.empty((n_frames, n_joints, 3, 3)) if rotmat else np.empty((0, 0, 0, 0))
    out_e = np.empty((n_frames, n_joints, 3)) if euler_order is not None else empty
    _convert(aa, params, quat, rotmat, euler_order is not None, out_q, out_r, out_e)
    result: dict[str, np.ndarray] = {}
    if quat:
        result["quat"] = out_q
    if rotmat:
        result["rotmat"] = out_r
    if euler_order is not None:
        result["euler"] = out_e
    return result


def _euler_params(euler_order: str | list[str] | None, n_joints: int) -> np.ndarray:
    if euler_order is None:
        return np.zeros((n_joints, 6), dtype=np.int64)
    if isinstance(euler_order, str):
        return np.tile(euler_order_params(euler_order), (n_joints, 1))
    if len(euler_order) != n_joints:
        raise ValueError(f"{len(euler_order)} Euler orders for {n_joints} joints")
    return np.stack([euler_order_params(o) for o in euler_order])


def span_links(bounds: np.ndarray, n_frames: int) -> np.ndarray | None:
    """(F,) int8: 1 where frame f continues frame f − 1 inside one [start, stop) of ``bounds``
    (S, 2), else 0; None when spans overlap (then signs need :func:`quat_sign_continuous_spans`,
    which treats spans one after the other)."""
    b = np.asarray(bounds, dtype=np.int64).reshape(-1, 2)
    if b.size and (b.min() < 0 or b.max() > n_frames or np.any(b[:, 1] < b[:, 0])):
        raise ValueError("sequence bounds outside the quaternion frames")
    b = b[b[:, 1] > b[:, 0]]
    order = b[np.argsort(b[:, 0], kind="stable")]
    if len(order) > 1 and np.any(order[1:, 0] < order[:-1, 1]):
        return None
    links = np.zeros(max(n_frames, 1), dtype=np.int8)
    for start, stop in order:
        links[start + 1 : stop] = 1
    return links


def rotation_representations(
    axis_angle: np.ndarray,
    names: tuple[str, ...] | list[str],
    euler_order: str | list[str],
    *,
    dtype: type = np.float32,
    bounds: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """(F, J, 3) axis-angle (radians) → the named representations among ``quat`` (F, J, 4)
    wxyz, ``rotmat`` (F, J, 3, 3), ``euler`` (F, J, 3) radians in ``euler_order``, ``rot6d``
    and ``rot6d_rows`` (F, J, 6), written straight into ``dtype`` arrays by one compiled pass
    (every value computed in float64 and rounded once: the numbers of
    :func:`rotations_from_axis_angle` followed by ``astype(dtype)``). With ``bounds`` (S, 2),
    quaternions are sign-continuous within each [start, stop) (the numbers of
    :func:`quat_sign_continuous_spans` on the float64 quaternions, then rounded); else
    canonical (w ≥ 0)."""
    aa = np.ascontiguousarray(axis_angle)
    if aa.ndim != 3 or aa.shape[-1] != 3:
        raise ValueError(f"need axis-angle (F, J, 3), got {aa.shape}")
    if aa.dtype not in (np.float32, np.float64):
        aa = aa.astype(np.float64)
    n_frames, n_joints = aa.shape[:2]
    wanted = set(names)
    unknown = wanted - {"quat", "rotmat", "euler", "rot6d", "rot6d_rows"}
    if unknown:
        raise ValueError(f"unknown representation {sorted(unknown)[0]!r}")
    links = None if bounds is None or "quat" not in wanted else span_links(bounds, n_frames)
    if bounds is not None and "quat" in wanted and links is None:  # overlapping spans
        out = rotation_representations(aa, names, euler_order, dtype=np.float64)
        out["quat"] = quat_sign_continuous_spans(out["quat"], bounds)
        return {k: v.astype(dtype) for k, v in out.items()}
    params = _euler_params(euler_order if "euler" in wanted else None, n_joints)

    def array(name: str, row: tuple[int, ...]) -> np.ndarray:
        shape = (n_frames, n_joints, *row) if name in wanted else (0, 0) + (0,) * len(row)
        return np.empty(shape, dtype=dtype)

    out = {
        "quat": array("quat", (4,)),
        "rotmat": array("rotmat", (3, 3)),
        "euler": array("euler", (3,)),
        "rot6d": array("rot6d", (6,)),
        "rot6d_rows": array("rot6d_rows", (6,)),
    }
    _convert_all(
        aa, params, np.zeros(0, dtype=np.int8) if links is None else links,
        "quat" in wanted, "rotmat" in wanted, "euler" in wanted,
        "rot6d" in wanted, "rot6d_rows" in wanted,
        out["quat"], out["rotmat"], out["euler"], out["rot6d"], out["rot6d_rows"],
    )  # fmt: skip
    return {name: out[name] for name in names}


@numba.njit(cache=True, nogil=True)
def _sign_spans(quat, bounds):  # noqa: ANN001
    n_joints = quat.shape[1]
    for s in range(bounds.shape[0]):
        start, stop = bounds[s, 0], bounds[s, 1]
        for jj in range(n_joints):
            if stop - start < 2:
                continue
            p0, p1 = quat[start, jj, 0], quat[start, jj, 1]
            p2, p3 = quat[start, jj, 2], quat[start, jj, 3]
            flipped = False
            for f in range(start + 1, stop):
                r0, r1, r2, r3 = quat[f, jj, 0], quat[f, jj, 1], quat[f, jj, 2], quat[f, jj, 3]
                # the raw neighbours' dot decides, and flips accumulate (quat_sign_continuous)
                if r0 * p0 + r1 * p1 + r2 * p2 + r3 * p3 < 0:
                    flipped = not flipped
                p0, p1, p2, p3 = r0, r1, r2, r3
                if flipped:
                    quat[f, jj, 0], quat[f, jj, 1] = -r0, -r1
                    quat[f, jj, 2], quat[f, jj, 3] = -r2, -r3
    return 0


def quat_sign_continuous_spans(quat: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(F, J, 4) quaternions made sign-continuous over time within each [start, stop) of
    ``bounds`` (S, 2), the first frame of each span kept: the same result as
    ``compute.rotations.quat_sign_continuous`` on every span, in one compiled pass."""
    q = np.array(quat, dtype=np.float64, copy=True, order="C")
    if q.ndim != 3 or q.shape[-1] != 4:
        raise ValueError(f"need quaternions (F, J, 4), got {q.shape}")
    b = np.ascontiguousarray(np.asarray(bounds, dtype=np.int64).reshape(-1, 2))
    if b.size and (b.min() < 0 or b.max() > q.shape[0] or np.any(b[:, 1] < b[:, 0])):
        raise ValueError("sequence bounds outside the quaternion frames")
    _sign_spans(q, b)
    return q
