"""Digital translational controllers of Karydes (2020), thesis section 3.2, vectorised over agents.

The design model is the thesis' double integrator per axis (eq. 3.17-3.22): the attitude loop is
assumed perfect and ``u`` is the net acceleration, held over one controller period ``T_s``
(zero-order hold). Every controller here is linear, identical on the three axes and uses a
symmetric saturation (eq. 3.26), so it commutes with the NED -> world (x east, y north, z up)
change of axes (a permutation and a sign flip): the laws are applied to world-frame (N, 3) arrays
directly, which is the same as converting to NED, controlling and converting back. Only the
per-axis limits (``u_sat``) must be given in world axes. The thrust that realises ``u`` is
T = m (g + u_z) in the world frame (thesis eq. 3.20 is T = m (g - u_z) with z down).

Contents:
    gain synthesis: :func:`velocity_gains` (eq. 3.28), :func:`conjugate_poles` (eq. 3.40),
    :func:`position_gains_from_poles` / :func:`position_gains` (eq. 3.36-3.39),
    :func:`tracker_gains` (section 3.2.5, same synthesis without feed-forward);
    laws: :func:`sat` (eq. 3.26), :func:`velocity_limiter` (eq. 3.45), :class:`VelocityPI`
    (eq. 3.23-3.25 as restored in papers/README.md), :class:`PositionPID` (eq. 3.29-3.30),
    :class:`TrackerControl` (eq. 3.41-3.42) and :class:`ThesisController`, which selects one of
    them per agent from the setpoint mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmscene.core.setpoint import Mode
from swarmscene.core.vectors import every

# --------------------------------------------------------------------------- gain synthesis


@dataclass(frozen=True)
class VelocityGains:
    """Gains of the velocity PI (thesis eq. 3.28): K_Pv, K_Iv, K_Fv in 1/s, anti-windup K_Wv in s."""

    K_Pv: float
    K_Iv: float
    K_Fv: float
    K_Wv: float = 0.5


@dataclass(frozen=True)
class PositionGains:
    """Gains of the position PID (eq. 3.36-3.37): K_Pr, K_Ir, K_Fr in 1/s^2, K_Dr in 1/s, K_Wr in s^2."""

    K_Pr: float
    K_Ir: float
    K_Dr: float
    K_Fr: float
    K_Wr: float = 50.0


@dataclass(frozen=True)
class TrackerGains:
    """Gains of the tracker control (section 3.2.5): K_Pt, K_It in 1/s^2, K_Dt in 1/s, K_Wt in s^2."""

    K_Pt: float
    K_It: float
    K_Dt: float
    K_Wt: float = 5.0


def velocity_gains(p_1: float, p_2: float, T_s: float, K_Wv: float = 0.5) -> VelocityGains:
    """Velocity PI gains placing the closed-loop poles of eq. 3.27 at ``p_1 <= p_2`` (eq. 3.28).

    K_Fv puts the transfer function's zero on the slow pole ``p_2``, so the step response is the
    first-order one of ``p_1``. Thesis values: p = (0.30, 0.80), T_s = 0.1 s give K_Pv = 9.0,
    K_Iv = 1.4, K_Fv = 7.0 (K_Wv = 0.5 s was tuned by simulation, not synthesised).
    """
    if not 0.0 < p_1 <= p_2 < 1.0:
        raise ValueError(f"need 0 < p_1 <= p_2 < 1 (got {p_1}, {p_2})")
    K_Pv = (2.0 - p_1 - p_2) / T_s
    K_Iv = K_Pv + (p_1 * p_2 - 1.0) / T_s
    return VelocityGains(K_Pv=K_Pv, K_Iv=K_Iv, K_Fv=K_Iv / (1.0 - p_2), K_Wv=K_Wv)


def conjugate_poles(omega: float, xi: float, T_s: float) -> tuple[complex, complex, float]:
    """Discrete poles p_1, p_2 = conj(p_1), p_3 = |p_1| from (omega, xi) (thesis eq. 3.40).

    s = -omega (xi + j sqrt(1 - xi^2)), p_1 = exp(T_s s), with omega > 0 and 0 < xi < 1. The thesis
    also asks omega < 2 pi / T_s: beyond it the sampled poles alias (the period is too long for the
    bandwidth asked). That is not an error here, so a coarse guidance period still gives a defined,
    stable (if sluggish) design instead of a crash.
    """
    if not (omega > 0.0 and 0.0 < xi < 1.0):
        raise ValueError(f"need omega > 0 and 0 < xi < 1 (got {omega}, {xi})")
    s = -omega * (xi + 1j * np.sqrt(1.0 - xi * xi))
    p_1 = complex(np.exp(T_s * s))
    return p_1, p_1.conjugate(), abs(p_1)


def position_gains_from_poles(
    p_1: complex, p_2: complex, p_3: float, T_s: float, K_Wr: float = 50.0
) -> PositionGains:
    """Position PID gains placing the poles of eq. 3.33 at p_1, p_2, p_3 (eq. 3.36-3.39).

    The characteristic polynomial's wanted coefficients are ā_2 = -(p_1 + p_2 + p_3),
    ā_1 = p_1 p_2 + p_2 p_3 + p_3 p_1, ā_0 = -p_1 p_2 p_3 (eq. 3.38-3.39); K_Fr puts the zero
    b̄_0 = p_3 on the real pole.
    """
    a_2 = -(p_1 + p_2 + p_3).real
    a_1 = (p_1 * p_2 + p_2 * p_3 + p_3 * p_1).real
    a_0 = -(p_1 * p_2 * p_3).real
    K_Dr = (a_0 - a_1 + a_2 + 7.0) / (4.0 * T_s)
    K_Ir = 2.0 / T_s**2 * (a_1 + 2.0 * T_s * K_Dr - 3.0)
    K_Pr = 2.0 / T_s**2 * (a_2 - T_s * K_Dr + 3.0)
    return PositionGains(K_Pr=K_Pr, K_Ir=K_Ir, K_Dr=K_Dr, K_Fr=K_Ir / (1.0 - p_3), K_Wr=K_Wr)


def position_gains(omega_r: float, xi_r: float, T_s: float, K_Wr: float = 50.0) -> PositionGains:
    """Position PID gains from the tuning pair (omega_r, xi_r) (eq. 3.40 then 3.36-3.39).

    Thesis: omega_r = 0.23, xi_r = 0.71, T_s = 0.1 s give K_Pr = 0.10, K_Ir = 0.00084,
    K_Dr = 0.48, K_Fr = 0.052 (K_Wr = 50 s^2 tuned by simulation).
    """
    return position_gains_from_poles(*conjugate_poles(omega_r, xi_r, T_s), T_s=T_s, K_Wr=K_Wr)


def tracker_gains(omega_t: float, xi_t: float, T_s: float, K_Wt: float = 5.0) -> TrackerGains:
    """Tracker gains: the error dynamics 3.42-3.44 equal the position loop's, so the same pole
    placement applies (the feed-forward gain is not used: the target's input ū is fed directly).

    Thesis: omega_t = 1.5, xi = 0.71, T_s = 0.1 s give K_Pt = 4.1, K_It = 0.20, K_Dt = 2.9.
    """
    g = position_gains(omega_t, xi_t, T_s)
    return TrackerGains(K_Pt=g.K_Pr, K_It=g.K_Ir, K_Dt=g.K_Dr, K_Wt=K_Wt)


# --------------------------------------------------------------------------- static laws


def sat(a: np.ndarray, u_sat: float | np.ndarray) -> np.ndarray:
    """Symmetric saturation (eq. 3.26): clip each component to [-u_sat, u_sat]."""
    # minimum(maximum()) is np.clip's result (NaN included) at half the call's fixed cost
    out = np.maximum(a, -u_sat)
    return np.minimum(out, u_sat, out=out)


def velocity_limiter(
    u_inf: np.ndarray,
    v: np.ndarray,
    v_lim: np.ndarray | float,
    K_lim: float,
    eps_lim: float,
) -> np.ndarray:
    """Switching law u_lim that keeps |v| below v̄_lim on each axis (eq. 3.45).

    Args:
        u_inf: (N, 3) unbounded command of the position or tracker law, m/s^2.
        v: (N, 3) velocity, m/s.
        v_lim: velocity limit v̄_lim, m/s: scalar, (N,) per agent or (N, 3) per axis.
        K_lim: limiter gain, 0 < K_lim < 2 / T_s (thesis: 2.5 1/s).
        eps_lim: anti-chattering threshold ε_lim (thesis: 3 σ of the velocity noise); a limit at or
            below it stops the agent with u_~ = -K_lim v instead of switching.

    Returns:
        (N, 3) u_lim, to be saturated by :func:`sat`. Applied per axis as in the thesis, so the
        speed bound of the vector is sqrt(3) v̄_lim on a diagonal.
    """
    if not isinstance(v_lim, float):
        v_lim = np.asarray(v_lim, dtype=float)
        if v_lim.ndim == 1:
            v_lim = v_lim[:, None]
    elif not v_lim > eps_lim:  # one scalar limit at or below the threshold: brake everywhere
        return -K_lim * v
    # -K_lim (v -+ v_lim), then the bound on u_inf, in place (the same products and bounds)
    u_plus = v - v_lim
    u_plus *= -K_lim
    u_minus = v + v_lim
    u_minus *= -K_lim
    u_lim = np.where(v > 0.0, np.minimum(u_inf, u_plus, out=u_plus), np.maximum(u_inf, u_minus, out=u_minus))
    return u_lim if isinstance(v_lim, float) else np.where(v_lim > eps_lim, u_lim, -K_lim * v)


# --------------------------------------------------------------------------- dynamic laws


class _IntegralLaw:
    """Common part of the three laws: one integral state x_I per agent and axis.

    Each law is split in two calls so that the limiter and the saturation can sit between them:
    ``unbounded`` gives u_∞ (eq. 3.23 / 3.29 / 3.41), ``integrate`` advances x_I with the anti-windup
    term K_W (u_∞ - u) (eq. 3.24 / 3.30 / 3.42), where u is the input actually applied.
    """

    def __init__(self, n: int) -> None:
        self.x_I = np.zeros((n, 3))

    def _advance(self, error: np.ndarray, u_inf: np.ndarray, u: np.ndarray, K_W: float,
                 active: np.ndarray | None) -> None:
        step = u_inf - u  # error + K_W (u_inf - u), in place: the same product and sum
        step *= K_W
        step += error
        if active is None:
            self.x_I += step
        else:
            self.x_I += np.where(active[:, None], step, 0.0)


class VelocityPI(_IntegralLaw):
    """Velocity PI with feed-forward and anti-windup (thesis eq. 3.23-3.25, 3.27-3.28).

    u_∞ = -K_Iv x_Iv - K_Pv v + K_Fv v̄, u = sat(u_∞), x_Iv(k+1) = x_Iv + v - v̄ + K_Wv (u_∞ - u).
    The lost equations 3.23-3.25 are restored from the transfer function 3.27 (papers/README.md).
    """

    def __init__(self, gains: VelocityGains, n: int) -> None:
        super().__init__(n)
        self.gains = gains

    def unbounded(self, v: np.ndarray, v_ref: np.ndarray) -> np.ndarray:
        """u_∞ = -K_Iv x_Iv - K_Pv v + K_Fv v̄ (eq. 3.23), before the saturation."""
        g = self.gains
        return -g.K_Iv * self.x_I - g.K_Pv * v + g.K_Fv * v_ref

    def integrate(self, v, v_ref, u_inf, u, active=None) -> None:
        """x_Iv += v - v̄ + K_Wv (u_∞ - u) (eq. 3.24), for the ``active`` agents only (all when None)."""
        self._advance(v - v_ref, u_inf, u, self.gains.K_Wv, active)

    def reset(self, mask: np.ndarray, v: np.ndarray) -> None:
        """Bumpless start for agents in ``mask``: an agent already at v̄ = v gets u_∞ = 0.

        The law is not shift-invariant (K_Fv ≠ K_Pv); its steady state at v = v̄ has
        x_Iv = (K_Fv - K_Pv) v̄ / K_Iv, so the integral starts there instead of at zero.
        """
        g = self.gains
        self.x_I[mask] = (g.K_Fv - g.K_Pv) / g.K_Iv * v[mask]


class PositionPID(_IntegralLaw):
    """Position PID with feed-forward and anti-windup (thesis eq. 3.29-3.30).

    u_∞ = -K_Ir x_Ir - K_Pr r - K_Dr v + K_Fr r̄, x_Ir(k+1) = x_Ir + r - r̄ + K_Wr (u_∞ - u).
    """

    def __init__(self, gains: PositionGains, n: int) -> None:
        super().__init__(n)
        self.gains = gains

    def unbounded(self, r: np.ndarray, v: np.ndarray, r_ref: np.ndarray) -> np.ndarray:
        """u_∞ = -K_Ir x_Ir - K_Pr r - K_Dr v + K_Fr r̄ (eq. 3.29), before the limiter and saturation."""
        g = self.gains
        return -g.K_Ir * self.x_I - g.K_Pr * r - g.K_Dr * v + g.K_Fr * r_ref

    def integrate(self, r, r_ref, u_inf, u, active=None) -> None:
        """x_Ir += r - r̄ + K_Wr (u_∞ - u) (eq. 3.30), for the ``active`` agents only (all when None)."""
        self._advance(r - r_ref, u_inf, u, self.gains.K_Wr, active)

    def reset(self, mask: np.ndarray, r: np.ndarray) -> None:
        """Bumpless start: x_Ir = (K_Fr - K_Pr) r / K_Ir, so an agent at rest on r̄ = r gets u = 0.

        Without it the law (which is not shift-invariant) would kick an agent holding far from the
        origin; with it a step from any r responds exactly like the thesis' step from 0 (Fig. 3.8).
        """
        g = self.gains
        self.x_I[mask] = (g.K_Fr - g.K_Pr) / g.K_Ir * r[mask]


class TrackerControl(_IntegralLaw):
    """Tracker control (thesis eq. 3.41-3.42): follow a target (r̄, v̄, input ū) with an offset.

    u_∞ = -K_It x_It - K_Pt e_r - K_Dt e_v + ū, e_r = r - r̄, e_v = v - v̄,
    x_It(k+1) = x_It + e_r + K_Wt (u_∞ - u). (Eq. 3.41 prints K_Pr, K_Dv: read K_Pt, K_Dt.)
    """

    def __init__(self, gains: TrackerGains, n: int) -> None:
        super().__init__(n)
        self.gains = gains

    def unbounded(self, r, v, r_ref, v_ref, u_ref) -> np.ndarray:
        """u_∞ = -K_It x_It - K_Pt e_r - K_Dt e_v + ū (eq. 3.41), before the limiter and saturation."""
        g = self.gains
        return -g.K_It * self.x_I - g.K_Pt * (r - r_ref) - g.K_Dt * (v - v_ref) + u_ref

    def integrate(self, r, r_ref, u_inf, u, active=None) -> None:
        """x_It += e_r + K_Wt (u_∞ - u) (eq. 3.42), for the ``active`` agents only (all when None)."""
        self._advance(r - r_ref, u_inf, u, self.gains.K_Wt, active)

    def reset(self, mask: np.ndarray) -> None:
        """Agents in ``mask`` start tracking with x_It = 0: the law is shift-invariant in e_r, e_v."""
        self.x_I[mask] = 0.0


# --------------------------------------------------------------------------- mode selection

_VELOCITY, _POSITION, _TRACKER = 0, 1, 2
_FAMILY = np.array([_POSITION, _VELOCITY, _TRACKER, _POSITION], dtype=np.int8)
"""Law used for each :class:`Mode` value (POSITION, VELOCITY, TRACK, HOLD)."""
assert [int(m) for m in Mode] == [0, 1, 2, 3]


class ThesisController:
    """The three thesis laws for N agents, one chosen per agent and tick from its setpoint mode.

    POSITION and HOLD -> position PID on r̄ (the thesis law has no velocity or acceleration
    feed-forward, so ``v_ref``/``u_ref`` are ignored there); VELOCITY -> velocity PI on v̄;
    TRACK -> tracker on (r̄, v̄, ū). The velocity limiter (when ``v_lim`` is given) acts on the
    position and tracker laws only, as in the thesis (velocity control sets v explicitly).
    When an agent changes law, the new law's integral state is restarted bumplessly.

    Anti-windup with the limiter (a choice: the thesis does not say): the integral sees
    K_W (u_∞ - u) with u = sat(u_lim), i.e. the limiter's cut as well as the saturation. Feeding back
    only the saturation, K_W (u_lim - u), lets x_I wind up for the whole limited phase: in the
    Fig. 3.15 scenario the agent then overshoots to ~148 m after the release, which the figure does
    not show; with the choice made here it settles on 100 m without overshoot.

    Args:
        n: number of agents.
        velocity, position, tracker: gains of each law.
        u_sat: saturation u_sat, m/s^2: scalar or (3,) per world axis.
        K_lim, eps_lim: velocity limiter gain (1/s) and anti-chattering threshold (m/s).
    """

    def __init__(self, n: int, velocity: VelocityGains, position: PositionGains,
                 tracker: TrackerGains, u_sat: float | np.ndarray,
                 K_lim: float = 2.5, eps_lim: float = 0.0) -> None:
        self.velocity = VelocityPI(velocity, n)
        self.position = PositionPID(position, n)
        self.tracker = TrackerControl(tracker, n)
        self.u_sat = np.asarray(u_sat, dtype=float)
        self.K_lim = K_lim
        self.eps_lim = eps_lim
        self.family = np.full(n, -1, dtype=np.int8)
        """(N,) law each agent used at the previous tick (-1 before the first)."""
        self._one_law: int | None = None
        """The law every agent used at the previous tick, if they all used one."""

    def step(self, mode: np.ndarray, r: np.ndarray, v: np.ndarray, r_ref: np.ndarray,
             v_ref: np.ndarray, u_ref: np.ndarray,
             v_lim: np.ndarray | float | None = None) -> np.ndarray:
        """One controller period: return the saturated input u (N, 3), m/s^2, and advance states.

        Args:
            mode: (N,) :class:`Mode` values.
            r: (N, 3) positions.
            v: (N, 3) velocities.
            r_ref: (N, 3) reference positions r̄.
            v_ref: (N, 3) reference velocities v̄.
            u_ref: (N, 3) reference inputs ū.
            v_lim: velocity limit v̄_lim (scalar or (N,)), or None for none.
        """
        first = int(mode[0]) if mode.size else int(Mode.VELOCITY)
        if every(mode == first):  # one mode, so one law, for every agent (the usual case)
            law = int(_FAMILY[first])
            if self._one_law != law:  # else every agent used it last tick: nothing restarts
                self._restart(_FAMILY[mode], r, v)
                self._one_law = law
            return self.step_steady(law, r, v, r_ref, v_ref, u_ref, v_lim)
        family = _FAMILY[mode]
        self._one_law = None
        self._restart(family, r, v)
        is_vel = family == _VELOCITY
        is_pos = family == _POSITION
        u_inf = np.where(
            is_vel[:, None],
            self.velocity.unbounded(v, v_ref),
            np.where(is_pos[:, None], self.position.unbounded(r, v, r_ref),
                     self.tracker.unbounded(r, v, r_ref, v_ref, u_ref)),
        )
        u_cmd = u_inf
        if v_lim is not None:
            u_cmd = np.where(is_vel[:, None], u_inf,
                             velocity_limiter(u_inf, v, v_lim, self.K_lim, self.eps_lim))
        u = sat(u_cmd, self.u_sat)
        self.velocity.integrate(v, v_ref, u_inf, u, is_vel)
        self.position.integrate(r, r_ref, u_inf, u, is_pos)
        self.tracker.integrate(r, r_ref, u_inf, u, family == _TRACKER)
        return u

    def steady_law(self, mode: np.ndarray) -> int | None:
        """The law every agent ran at the previous tick, when ``mode`` keeps each of them on it (so
        :meth:`step` restarts no integral and runs :meth:`step_steady` with it); else None."""
        if self._one_law is None or not mode.size:
            return None
        first = int(mode[0])
        if not 0 <= first < len(_FAMILY) or int(_FAMILY[first]) != self._one_law:
            return None
        return self._one_law if every(mode == first) else None

    def stacked(self, law: int, x_I: np.ndarray) -> ThesisController:
        """A controller with this one's gains and limits over the agents of B worlds stacked along
        the first axis (the world axis, docs/batched.md), whose law ``law`` integrates ``x_I``
        ((B N, 3), a view of the worlds' own integral states) in place. Its :meth:`step_steady`
        is each world's :meth:`step`, bit for bit, when every world's :meth:`steady_law` is
        ``law``: the same elementwise operations on the same values."""
        twin = ThesisController(0, self.velocity.gains, self.position.gains, self.tracker.gains,
                                self.u_sat, self.K_lim, self.eps_lim)
        (twin.velocity, twin.position, twin.tracker)[law].x_I = x_I
        return twin

    def step_steady(self, family: int, r: np.ndarray, v: np.ndarray, r_ref: np.ndarray,
                    v_ref: np.ndarray, u_ref: np.ndarray, v_lim: np.ndarray | float | None) -> np.ndarray:
        """:meth:`step` when every agent uses law ``family``: the same operations on the same
        values (so the same bits), without the two laws whose results the selection drops. The
        idle laws' integrals are left as they are: an agent entering a law restarts its integral."""
        if family == _VELOCITY:
            u_inf = self.velocity.unbounded(v, v_ref)
            u = sat(u_inf, self.u_sat)
            self.velocity.integrate(v, v_ref, u_inf, u)
            return u
        law: _IntegralLaw  # the position or the tracker law: both integrate alike
        if family == _POSITION:
            law, u_inf = self.position, self.position.unbounded(r, v, r_ref)
        else:
            law, u_inf = self.tracker, self.tracker.unbounded(r, v, r_ref, v_ref, u_ref)
        u_cmd = u_inf if v_lim is None else velocity_limiter(u_inf, v, v_lim, self.K_lim, self.eps_lim)
        u = sat(u_cmd, self.u_sat)
        law.integrate(r, r_ref, u_inf, u)
        return u

    def _restart(self, family: np.ndarray, r: np.ndarray, v: np.ndarray) -> None:
        changed = family != self.family
        if changed.any():
            self.velocity.reset(changed & (family == _VELOCITY), v)
            self.position.reset(changed & (family == _POSITION), r)
            self.tracker.reset(changed & (family == _TRACKER))
            self.family = family
