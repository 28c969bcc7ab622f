"""6-DOF quadrotor of Karydes (2020), thesis section 3.1, vectorised over N agents.

Frames. The thesis writes the model in North-East-Down with a front-right-down body frame
(thrust along -z_b). The engine's world frame is x east, y north, z up (core/state.py), so this
module uses a front-left-up body frame (thrust along +z_b): the thesis' world vectors map by
(x, y, z)_world = (y, x, -z)_NED and its body vectors by (x, y, z)_FLU = (x, -y, -z)_FRD.
Eq. 3.5 then reads m v̇ = -m g e_3 + R T e_3, and the moments of eq. 3.14 become
(M_x, -M_y, -M_z) — :func:`thesis_mixer_matrix` keeps the thesis' form and the tests check that
:func:`mixer_matrix` is its conversion.

State per agent: p (N, 3) m, v (N, 3) m/s (world), q (N, 4) unit quaternion (w, x, y, z) body to
world, omega (N, 3) rad/s body rates. Inputs: rotor speeds ϖ (N, 4) rad/s, reached instantly and
with negligible rotor inertia (thesis 3.1.5: J_m ≈ 0, so the gyroscopic moment G of eq. 3.11 and
the J_m ϖ̇ term vanish).

Integration: classical RK4 with the wrench held over the step (the controller's zero-order hold),
quaternion renormalised after each step. RK4 rather than semi-implicit Euler because it is exact
for the polynomial motions the tests check (free fall, hover) and keeps the rotational energy and
angular momentum of a free, tumbling body within ~2e-9 (relative) over 10 s at 240 Hz instead of
the O(dt) drift of a first-order scheme.

This module holds the airframes, the mixer matrix of eq. 3.15 and rotation helpers. The physics
step (allocation eq. 3.16, wrench eq. 3.15, the right-hand side of eq. 3.4-3.8 and RK4) runs
compiled per agent in kernels.py; its numpy form is the tests' oracle (tests/oracles/quadrotor.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

GRAVITY = 9.81
"""g, m/s^2."""

# rotor i (thesis numbering 1..4) position directions in the FLU body frame, eq. 3.12 converted:
# 1 front-right, 2 front-left, 3 rear-left, 4 rear-right.
_ROTOR_DIRECTIONS = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0]])
_YAW_SIGN_FLU = np.array([-1.0, 1.0, -1.0, 1.0])
"""Drag-torque sign of each rotor about +z_FLU: the thesis has +k_D ϖ_1^2 about z_FRD (down)."""


@dataclass(frozen=True)
class Airframe:
    """Physical parameters of one quadrotor type (X configuration).

    Attributes:
        name: identifier used in config (``airframe: crazyflie``).
        mass: m, kg.
        inertia: diagonal of J, kg m^2 (body x, y, z).
        arm: d, distance from the centre of gravity to each rotor axis, m (eq. 3.12).
        k_T: thrust coefficient k_T, N / (rad/s)^2 (eq. 3.9).
        k_D: drag-torque coefficient k_D, N m / (rad/s)^2 (eq. 3.11).
        rotor_speed_min, rotor_speed_max: limits on ϖ_i, rad/s.
        source: where the numbers come from.
        drag: linear drag per unit mass along the body axes (x, y, z), 1/s: F = m R diag(drag)
            R^T (w - v) (rotor drag, linear in airspeed). Only the wind's part m R D R^T w is
            applied (the model has no still-air drag), by the ``disturbances`` wind phase.
    """

    name: str
    mass: float
    inertia: tuple[float, float, float]
    arm: float
    k_T: float
    k_D: float
    rotor_speed_min: float
    rotor_speed_max: float
    source: str = ""
    drag: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @cached_property
    def J(self) -> np.ndarray:
        """(J_x, J_y, J_z): the airframe's principal moments of inertia, kg m^2 (the J of eq. 3.7)."""
        return np.array(self.inertia, dtype=float)

    @cached_property
    def gyro(self) -> np.ndarray:
        """(J_k - J_j) / J_i for (i, j, k) cyclic: the gyroscopic coefficients of eq. 3.7."""
        J = self.J
        return (J[[2, 0, 1]] - J[[1, 2, 0]]) / J

    @cached_property
    def mixer(self) -> np.ndarray:
        """The 4x4 matrix from squared rotor speeds to [T, M_x, M_y, M_z] (eq. 3.13-3.15, built once)."""
        return mixer_matrix(self.arm, self.k_T, self.k_D)

    @cached_property
    def mixer_inverse(self) -> np.ndarray:
        """Inverse of :attr:`mixer`: the squared rotor speeds that give a thrust and three moments."""
        return np.linalg.inv(self.mixer)

    @property
    def hover_rotor_speed(self) -> float:
        """ϖ that carries m g on four equal rotors, rad/s."""
        return float(np.sqrt(self.mass * GRAVITY / (4.0 * self.k_T)))

    @property
    def max_thrust(self) -> float:
        """Collective thrust at ϖ_max, N."""
        return 4.0 * self.k_T * self.rotor_speed_max**2


_RPM2 = (60.0 / (2.0 * np.pi)) ** 2  # (N per rpm^2) -> (N per (rad/s)^2)

CRAZYFLIE = Airframe(
    name="crazyflie",
    mass=0.027,
    inertia=(1.4e-5, 1.4e-5, 2.17e-5),
    arm=0.0397,
    k_T=3.16e-10 * _RPM2,
    k_D=7.94e-12 * _RPM2,
    rotor_speed_min=0.0,
    rotor_speed_max=float(np.sqrt(2.25 * 0.027 * GRAVITY / (4.0 * 3.16e-10 * _RPM2))),
    source="Crazyflie 2.x as identified by Foerster (ETH 2015) and shipped in gym-pybullet-drones "
    "cf2x.urdf: m = 27 g, arm 39.7 mm, kf = 3.16e-10 N/rpm^2, km = 7.94e-12 N m/rpm^2, "
    "thrust-to-weight 2.25 (sets rotor_speed_max ~ 2.27e3 rad/s). Drag: Foerster's K_aero = "
    "(9.1785e-7, 9.1785e-7, 10.311e-7) kg/rad (as in gym-pybullet-drones' DRAG_COEFF) times the sum "
    "of the four hover rotor speeds (4 x 1516 rad/s), per kg: (0.206, 0.206, 0.232) 1/s.",
    drag=(0.206, 0.206, 0.232),
)

M330 = Airframe(
    name="m330",
    mass=1.0,
    inertia=(7.0e-3, 7.0e-3, 1.2e-2),
    arm=0.165,
    k_T=6.0e-6,
    k_D=1.0e-7,
    rotor_speed_min=0.0,
    rotor_speed_max=1000.0,
    source="~1 kg quad of the class flown in the CEM paper (M330, enclosing radius 0.28 m). The paper "
    "gives no inertial data, so these are assumptions: 330 mm motor-to-motor frame (arm 0.165 m), "
    "1.0 kg, inertia from 4 x 60 g motors on the arms plus a 0.5 kg central body, 8-inch propellers "
    "(k_T = 6e-6 N/(rad/s)^2, k_D/k_T = 1.7 cm), 1000 rad/s top speed (thrust-to-weight 2.4). "
    "Drag per kg taken equal to the Crazyflie's (an assumption: rotor drag scales with thrust, i.e. "
    "with mass, to first order).",
    drag=(0.206, 0.206, 0.232),
)

AIRFRAMES: dict[str, Airframe] = {a.name: a for a in (CRAZYFLIE, M330)}
"""Airframes selectable by name."""


# --------------------------------------------------------------------------- mixer (eq. 3.9-3.16)


def rotor_positions(arm: float) -> np.ndarray:
    """r_i of eq. 3.12 in the FLU body frame, (4, 3), m."""
    return arm / np.sqrt(2.0) * _ROTOR_DIRECTIONS


def mixer_matrix(arm: float, k_T: float, k_D: float) -> np.ndarray:
    """Matrix of ũ = [T, M_x, M_y, M_z]_FLU = mixer @ [ϖ_1^2 .. ϖ_4^2] (eq. 3.13-3.15, FLU).

    Built from the geometry: each rotor's thrust k_T ϖ^2 e_3 at r_i gives P = r_i x F_i (eq. 3.11)
    and its drag torque ±k_D ϖ^2 about z_b gives Q. T > 0 lifts.
    """
    r = rotor_positions(arm)
    return np.vstack([
        np.full(4, k_T),
        k_T * r[:, 1],          # (r x k_T e_3)_x = r_y k_T
        -k_T * r[:, 0],         # (r x k_T e_3)_y = -r_x k_T
        k_D * _YAW_SIGN_FLU,
    ])


def thesis_mixer_matrix(arm: float, k_T: float, k_D: float) -> np.ndarray:
    """The thesis' T of eq. 3.15 in its NED/FRD frames, written from eq. 3.13-3.14 (the matrix as
    printed has sign typos in its second row and in its inverse's first column and last row; the
    equations 3.13-3.14 are self-consistent with eq. 3.11-3.12, so they are used)."""
    a = arm * k_T / np.sqrt(2.0)
    return np.array([
        [-k_T, -k_T, -k_T, -k_T],
        [-a, a, a, -a],
        [a, a, -a, -a],
        [k_D, -k_D, k_D, -k_D],
    ])


THESIS_TO_FLU_WRENCH = np.diag([-1.0, 1.0, -1.0, -1.0])
"""Maps the thesis' [F_z, M_x, M_y, M_z]_FRD to [T, M_x, M_y, M_z]_FLU."""


# --------------------------------------------------------------------------- rotations


def _quadratic_basis() -> np.ndarray:
    """B (16, 9) with R.flat = (q q^T).flat @ B: R_b^o as a quadratic form of q = (w, x, y, z).

    One outer product and one matrix product instead of a dozen element-wise expressions (which
    matters more than flops for numpy on a few hundred agents). Homogeneous in q, so it is exact
    for unit quaternions and scales by |q|^2 otherwise.
    """
    w, x, y, z = range(4)
    entries = {
        0: [(1, w, w), (1, x, x), (-1, y, y), (-1, z, z)],
        1: [(2, x, y), (-2, w, z)], 2: [(2, x, z), (2, w, y)],
        3: [(2, x, y), (2, w, z)], 4: [(1, w, w), (-1, x, x), (1, y, y), (-1, z, z)],
        5: [(2, y, z), (-2, w, x)], 6: [(2, x, z), (-2, w, y)], 7: [(2, y, z), (2, w, x)],
        8: [(1, w, w), (-1, x, x), (-1, y, y), (1, z, z)],
    }
    B = np.zeros((16, 9))
    for col, terms in entries.items():
        for coef, j, k in terms:
            B[4 * j + k, col] += coef
    return B


_R_BASIS = _quadratic_basis()
_P1, _P2 = [1, 2, 0], [2, 0, 1]


def _outer(q: np.ndarray) -> np.ndarray:
    return (q[:, :, None] * q[:, None, :]).reshape(-1, 16)


def quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    """R_b^o (N, 3, 3) of unit quaternions (N, 4) (w, x, y, z), body to world."""
    return (_outer(q) @ _R_BASIS).reshape(-1, 3, 3)


def rotmat_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4) (w, x, y, z, w >= 0) of rotation matrices (N, 3, 3)."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(R).as_quat()
    q = xyzw[:, [3, 0, 1, 2]]
    return q * np.where(q[:, :1] < 0.0, -1.0, 1.0)


def yaw_to_quat(yaw: np.ndarray) -> np.ndarray:
    """Level attitude with heading ``yaw`` (N,) rad about world z, as quaternions (N, 4)."""
    q = np.zeros((yaw.shape[0], 4))
    q[:, 0] = np.cos(0.5 * yaw)
    q[:, 3] = np.sin(0.5 * yaw)
    return q


def euler_zyx(R: np.ndarray) -> np.ndarray:
    """(roll φ, pitch θ, yaw ψ) (N, 3) of R (N, 3, 3), ZYX sequence (eq. 3.2; R[2, 0] != ±1)."""
    return np.stack([
        np.arctan2(R[:, 2, 1], R[:, 2, 2]),
        -np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0)),
        np.arctan2(R[:, 1, 0], R[:, 0, 0]),
    ], axis=1)


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a x b for (N, 3) arrays (fewer numpy calls than np.cross on small N)."""
    return a[:, _P1] * b[:, _P2] - a[:, _P2] * b[:, _P1]
