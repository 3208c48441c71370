"""The odometry motion model (Thrun, Burgard & Fox, *Probabilistic Robotics*, 5.4).

The relative motion between two odometry poses ``(x, y, yaw)`` is decomposed into a first
rotation ``rot1`` (towards the direction of travel), a translation ``trans`` and a second
rotation ``rot2``. Sampling perturbs each part with zero-mean Gaussian noise whose
*variance* grows with the motion (the book's Table 5.6, as in ROS AMCL)::

    var(rot1)  = alpha1 * rot1^2 + alpha2 * trans^2
    var(trans) = alpha3 * trans^2 + alpha4 * (rot1^2 + rot2^2)
    var(rot2)  = alpha1 * rot2^2 + alpha2 * trans^2

and applies the noisy motion to every particle in its own frame. Two details follow AMCL:
below ``min_translation`` the direction of travel is undefined and ``rot1`` is 0 (an
in-place turn is all ``rot2``); the rotation noise of a backward move is computed from the
angle to the backward direction, not the near-180-degree ``rot1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.errors import ConfigError


def wrap(angle: NDArray[np.float64] | float) -> NDArray[np.float64]:
    """Angles wrapped to ``[-pi, pi)`` (rad)."""
    return (np.asarray(angle, dtype=np.float64) + math.pi) % (2 * math.pi) - math.pi


def wrap1(angle: float) -> float:
    """:func:`wrap` of one float, in Python floats (no array: ~20x cheaper). Bit-identical:
    Python's float ``%`` and numpy's remainder are both ``fmod`` plus the same sign fix."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def compose3(a: tuple[float, float, float], b: tuple[float, float, float]
             ) -> tuple[float, float, float]:
    """:func:`compose` of two single poses in Python floats (the same IEEE operations in
    the same order, so the same bits; the tracker calls it several times per scan)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap1(a[2] + b[2]))


def relative3(a: tuple[float, float, float], b: tuple[float, float, float]
              ) -> tuple[float, float, float]:
    """:func:`relative` of two single poses in Python floats (same bits, see :func:`compose3`)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return (c * dx + s * dy, -s * dx + c * dy, wrap1(b[2] - a[2]))


def _single(a: NDArray[np.float64], b: NDArray[np.float64]) -> bool:
    return a.shape == (3,) and b.shape == (3,)


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose composition ``a (+) b``: pose ``b`` given in the frame of ``a``; ``(..., 3)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if _single(a, b):
        return np.array(compose3(a.tolist(), b.tolist()))
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1],
                     a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     wrap(a[..., 2] + b[..., 2])], axis=-1)


def relative(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pose of ``b`` in the frame of ``a`` (``a (-) b``), so ``compose(a, relative(a, b)) = b``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if _single(a, b):
        return np.array(relative3(a.tolist(), b.tolist()))
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[..., 2] - a[..., 2])], axis=-1)


@dataclass(frozen=True)
class OdometryMotionParams:
    """Noise of the odometry motion model (dimensionless variance coefficients).

    Attributes:
        alpha1: rotation noise from rotation.
        alpha2: rotation noise from translation (rad^2 per m^2).
        alpha3: translation noise from translation.
        alpha4: translation noise from rotation (m^2 per rad^2).
        min_translation: below this translation (m) the motion counts as an in-place turn.

    Defaults: the simulated TurtleBot's wheel odometry errs by about 1 % of a turn and
    2-5 % of a drive per primitive (measured); the defaults allow ~10 % (std) so that the
    cloud covers the truth with margin.
    """

    alpha1: float = 0.01
    alpha2: float = 0.01
    alpha3: float = 0.01
    alpha4: float = 0.01
    min_translation: float = 0.01

    def __post_init__(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4", "min_translation"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"must be a number >= 0, got {value!r}",
                                  key=f"OdometryMotionParams.{name}")


def odometry_delta(odom_prev: NDArray[np.float64], odom_now: NDArray[np.float64],
                   min_translation: float = 0.01) -> tuple[float, float, float]:
    """``(rot1, trans, rot2)`` (rad, m, rad) of the motion between two odometry poses."""
    x0, y0, t0 = (float(v) for v in odom_prev)
    x1, y1, t1 = (float(v) for v in odom_now)
    trans = math.hypot(x1 - x0, y1 - y0)
    rot1 = 0.0 if trans < min_translation else wrap1(math.atan2(y1 - y0, x1 - x0) - t0)
    rot2 = wrap1(t1 - t0 - rot1)
    return rot1, trans, rot2


@numba.njit(cache=True)
def _move(p, noise, rot1, trans, rot2, sd_rot1, sd_trans, sd_rot2, out):  # pragma: no cover
    """Each particle moved by its noisy (rot1, trans, rot2): the numpy formulas of the
    tests' reference element by element, one pass instead of ~12 temporaries. libm's cos
    and sin are numpy's on the x86-64 builds checked (tests compare on real data)."""
    two_pi = 2.0 * math.pi
    for i in range(p.shape[0]):
        h_rot1 = rot1 - sd_rot1 * noise[i, 0]
        h_trans = trans - sd_trans * noise[i, 1]
        h_rot2 = rot2 - sd_rot2 * noise[i, 2]
        heading = p[i, 2] + h_rot1
        out[i, 0] = p[i, 0] + h_trans * math.cos(heading)
        out[i, 1] = p[i, 1] + h_trans * math.sin(heading)
        out[i, 2] = (heading + h_rot2 + math.pi) % two_pi - math.pi
    return out


def sample_odometry_motion(particles: NDArray[np.float64], odom_prev: NDArray[np.float64],
                           odom_now: NDArray[np.float64], params: OdometryMotionParams,
                           rng: np.random.Generator) -> NDArray[np.float64]:
    """Particles ``(N, 3)`` moved by the odometry motion with sampled noise (a new array)."""
    p = np.ascontiguousarray(particles, dtype=np.float64)
    rot1, trans, rot2 = odometry_delta(odom_prev, odom_now, params.min_translation)
    # Noise of a backward move comes from its angle to the backward direction.
    r1n = min(abs(rot1), abs(wrap1(rot1 - math.pi)))
    r2n = min(abs(rot2), abs(wrap1(rot2 - math.pi)))
    sd_rot1 = math.sqrt(params.alpha1 * r1n**2 + params.alpha2 * trans**2)
    sd_trans = math.sqrt(params.alpha3 * trans**2 + params.alpha4 * (r1n**2 + r2n**2))
    sd_rot2 = math.sqrt(params.alpha1 * r2n**2 + params.alpha2 * trans**2)
    noise = rng.standard_normal((p.shape[0], 3))
    return _move(p, noise, rot1, trans, rot2, sd_rot1, sd_trans, sd_rot2, np.empty_like(p))
