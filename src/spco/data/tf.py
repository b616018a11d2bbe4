"""The tf tree: frame names, the quaternion algebra of transforms, the path between two frames and
the transform composed along it.

A transform is held as seven numbers ``(x, y, z, qx, qy, qz, qw)``: the pose of a child frame in its
parent. Both readers of tf use this module: ``spco import-bag`` (:mod:`spco.data.bagreading`, every
transform of a recording, looked up at many times at once) and the ROS node
(:class:`spco.ros.messages.TfBuffer`, the latest transform of each edge).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["Edge", "Step", "compose", "compose_path", "frame_name", "invert", "path_between", "quat_mul",
           "rotate", "yaw"]

#: A tf edge: (parent frame, child frame).
Edge = tuple[str, str]
#: One step of a path: an edge, and whether it is walked from parent to child (``True``) or back.
Step = tuple[Edge, bool]


def frame_name(name: Any) -> str:
    """A frame id as tf compares them: without surrounding spaces and leading slashes."""
    return str(name or "").strip().lstrip("/")


def yaw(q: np.ndarray) -> np.ndarray:
    """Heading (rad, about z) of quaternions (..., 4) as x, y, z, w."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product ``a b`` of quaternions (..., 4) as x, y, z, w."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    u, w = q[..., :3], q[..., 3:]
    t = 2 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def compose(ta: np.ndarray, qa: np.ndarray, tb: np.ndarray, qb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T_a ∘ T_b (translation, quaternion)."""
    return ta + rotate(qa, tb), quat_mul(qa, qb)


def invert(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T⁻¹ of a transform (translation, unit quaternion)."""
    qi = q * np.array([-1.0, -1.0, -1.0, 1.0])
    return -rotate(qi, t), qi


def path_between(parent_of: Mapping[str, str], source: str, target: str) -> list[Step] | None:
    """The edges from frame ``source`` to frame ``target`` in the tree given by each child's parent:
    up from ``source`` to the frames' nearest common ancestor (edges walked back), then down to
    ``target``. ``[]`` when they are the same frame; ``None`` when the tree does not connect them."""

    def up(frame: str) -> list[str]:
        path = [frame]
        while path[-1] in parent_of and parent_of[path[-1]] not in path:
            path.append(parent_of[path[-1]])
        return path

    from_source, from_target = up(source), up(target)
    common = next((f for f in from_target if f in from_source), None)
    if common is None:
        return None
    down = from_target[: from_target.index(common) + 1][::-1]  # common ... target
    rise = from_source[: from_source.index(common) + 1]  # source ... common
    steps: list[Step] = [((parent_of[child], child), False) for child in rise[:-1]]
    steps += [((down[i], down[i + 1]), True) for i in range(len(down) - 1)]
    return steps


def compose_path(steps: Sequence[Step], value_of: Callable[[Edge], np.ndarray],
                 n: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The pose of a path's last frame in its first: ``(n, 3)`` translations and ``(n, 4)`` unit
    quaternions, composing each step's transform (``value_of(edge)``: ``(7,)`` or ``(n, 7)``; its
    quaternion normalised; inverted for a step walked back)."""
    t = np.zeros((n, 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    for edge, forwards in steps:
        value = np.broadcast_to(np.asarray(value_of(edge), dtype=np.float64), (n, 7))
        et, eq = value[:, :3], value[:, 3:] / np.linalg.norm(value[:, 3:], axis=1, keepdims=True)
        if not forwards:
            et, eq = invert(et, eq)
        t, q = compose(t, q, et, eq)
    return t, q
