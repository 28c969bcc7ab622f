"""``cem``: Containment Exclusion Mode, fluid-flow navigation around failed vehicles.

Romano, Uppaluru, Rastgoftar, Atkins (papers/cem-fluid-flow-navigation.md). While no vehicle has
failed, the formation's setpoints pass through unchanged. A ``hover`` (or ``motor_failure``) event
activates CEM: every failed vehicle becomes a doublet of planned exclusion radius a_p = a_f + delta + eps in a
uniform flow along the flight direction, each healthy agent's (phi, psi) is fixed from its position,
and every guidance tick the healthy agents slide along their streamlines (Algorithm 1, CalcXY of
Algorithm 2) as TRACK setpoints (position and first-difference velocity; altitude from the
formation). The method is :mod:`swarmscene.methods.cem`: the flow in :mod:`~swarmscene.methods.cem.flow`,
each tick one compiled call (:mod:`~swarmscene.methods.cem.kernels`, loaded at the first activation,
not at import), the hand-back rules and the safety record in :mod:`~swarmscene.methods.cem.handback`,
and the run (activations, flight direction, doublet strengths, the tick, the metrics) in
:class:`~swarmscene.methods.cem.mode.ContainmentExclusionMode`. This class adapts it to the plugin
contract: its options, the failure events, the avoidance step, the step-end and run-end hooks, and
the summary's wording of its verdicts.

Choices (the paper leaves these open):

* Flight direction: ``direction`` in degrees from world +x (counter-clockwise), or ``"auto"``: at
  activation, the heading of the healthy agents' mean velocity when it is at least 0.05 m/s, else
  the bearing from the healthy agents' centroid to the failed vehicles' centroid (a swarm at rest
  is taken to be heading for the failure in front of it).
* Failures at different times: each new ``hover`` event re-runs Algorithm 1's initialisation with
  every failed vehicle so far as a doublet; agents already under CEM restart from their current
  commands (no jump), the direction and flow origin of the running activation are kept, and the
  theorems are evaluated again for the new configuration. ``comm_loss`` events do not change the
  flow (a vehicle that lost its radio keeps flying, it is not an obstacle of its own).
* Failed vehicles' centres z_f are where they were when they failed (they hover, Assumption 3).
* Saddle noise (eq. 6), ``saddle_noise``: ``"printed"`` (default) draws it in every Newton
  iteration whose estimate is within a_p, as Algorithm 2 line 7 prints it; ``"gated"`` only while
  the update is still >= sigma and never in the last iteration, which keeps every command on its
  streamline exactly (eq. 4) at the price of a seed-independent run whose K = 1 peak (2.16 m/s)
  misses Fig. 10's 2.4 m/s. What each guarantees: see :mod:`swarmscene.methods.cem.flow`.
* Newton's loop (``newton_stop``): the paper's fixed n by default; ``"converged"`` the early stop
  shipped before. The branch guard (``branch_guard``, on): a departure, see
  :mod:`swarmscene.methods.cem.flow` for both and their measured effects.
* Several failures (eq. 1 prints a sum of full uniform-plus-doublet terms, which no figure of the
  paper flies), ``multi_failure_flow``: ``"ring_streamlines"`` (default) keeps one uniform term and
  gives each doublet the strength that keeps its a_p circle a streamline in the others' flow, the
  reading under which the section III-B claim "commands never come closer than delta + eps" holds;
  ``"unit_doublets"`` one uniform term and mu_f = a_p^2 per failure; ``"summed"`` eq. 1 as printed
  (N_f uniform terms: the same streamlines as ``"unit_doublets"`` with mu_f = a_p^2 / N_f, so the
  dividing rings shrink towards a_p / sqrt(N_f)). With one failure the three are eq. 1 exactly.
* Hand-back (the paper is silent: healthy agents "safely pass them before continuing with their
  individual trajectories", and its theorems cover CEM mode only), ``hand_back_rule``:
  ``"clear_path"`` (default, a departure from a silent paper) hands control back once every healthy
  agent's along-track coordinate (flow frame) exceeds that of the most downstream failed vehicle by
  ``handback_distance`` (default 2 a_p, where the doublet's distortion |f' - 1| = a_p^2 / r^2 has
  fallen to 1/4) *and* each healthy agent's formation setpoint, and the straight path from the agent
  to it, stay at least a_p from every failed vehicle (so a vehicle tracking within delta keeps
  a_f + eps clear of it, the bound CEM itself keeps). While the formation's setpoints are not clear
  CEM keeps control (its agents keep sliding downstream along their streamlines); after a hand-back
  the same test runs every tick and CEM re-activates (a new activation from the agents' positions)
  the moment a formation setpoint or its path comes within a_p of a failed vehicle. Measured:
  ``scenario=cem_six_vehicle events.0.at=21.34234639497493`` hands back at 32.14 s under the
  along-track rule alone, with the formation's slots upstream of the hovering lead, and agent 4 flies
  through it (1.45 mm at 32.98 s, under 2 eps = 0.56 m from 32.75 s; 0.76 mm at 32.99 s with
  newton_stop=converged); under ``"clear_path"`` CEM keeps control and no agent comes within
  a_f + eps (closest 1.35 m). The falsifier's failure-time search
  (``+sweep=falsify_failure scenario=cem_six_vehicle``, 100 TPE trials over time and agent) finds
  0.35 mm under ``"passed"`` (the lead failing at 19.94 s) and nothing closer than 1.35 m under
  ``"clear_path"`` (20 of its trials fail the lead between 19 and 22.3 s). The cost, stated plainly:
  where a slot is clear of the failed vehicle but the straight path back to it crosses a_p, CEM
  never hands back and the mission never completes. In ``cem_six_vehicle`` every failure of the
  lead from 18.0 to 22.3 s ends so: ``success False`` at 40 s, the healthy agents at x = 35-37 m
  (CEM flies them on downstream), the hovering lead at 21-25 m beside its formation's slots; the
  summary's ``mission`` line says why. No option routes the agents back around the failed vehicle
  yet (``"passed"`` completes those missions by flying through it).
  ``"passed"`` is that along-track rule alone (the rule shipped before). ``hand_back: false`` keeps
  CEM on for the rest of the run.
* Safety is measured from the recorded states every tick (``swarmscene_step_end``) from the first
  activation to the end of the run, after a hand-back too: exclusion margin of the commands (CEM's,
  or the formation's TRACK/POSITION setpoints once handed back), clearance of the actual positions
  from every failed vehicle, pairwise distances of healthy agents (2-D, the x-y plane of the
  theorems). Streamline drift, speeds, tracking error and the sliding step describe CEM's own
  commands, so they are measured while CEM is active only.

Metrics added at run end (SI units; distances in m, speeds in m/s):
    cem.a_f, cem.a_p: the failed vehicle's no-fly radius and the planned exclusion radius (eq. 4),
        as derived for this run (replays and plots read them here).
    cem.activations: number of (re)activations (a failure, or a formation setpoint that came within
        a_p of a failed vehicle after a hand-back). cem.handback_time: s, the last hand-back, or None
        if CEM held control at the end. cem.handback_blocked_time: s, the first tick at which every
        agent had passed but a formation setpoint or its path lay within a_p of a failed vehicle
        (None: never).
    cem.start_inside_exclusion: healthy agents already within a_p of a failure at an activation
        (outside every assumption: their first command is pushed out of the disk).
    cem.theorem1_precondition_met / cem.theorem2_precondition_met: the theorem's precondition
        (eq. 7-8 / eq. 16) held at every activation: the theorem's guarantee applies. Not met is not
        a failure of the run (Theorem 1 is conservative: the paper's own formation does not meet it);
        Theorem 2's is False when more than one vehicle has failed (it does not apply).
        Renamed from cem.theorem1_holds / cem.theorem2_holds, which metrics.json keeps beside them
        until the next release (:data:`CEM.RENAMED_METRICS`).
    cem.theorem2_applicable: one failure at every activation.
    cem.theorem1_p_min0, cem.theorem1_lambda_max, cem.theorem1_lhs, cem.theorem1_rhs,
        cem.theorem2_d_min0, cem.theorem2_bound: the numbers of the last activation.
    cem.psi_drift_max: max over agents and ticks of |psi_i(t) - psi_i0| of the commands.
    cem.psi_drift_per_agent: list (N,), the same per agent (0 for agents never under CEM).
    All of the following from the first activation to the end of the run (after a hand-back too):
    cem.min_exclusion_margin: min over commands of ||r_d - z_f|| - a_p (>= 0: outside a_p).
    cem.min_actual_clearance: min over healthy agents of ||r - z_f|| - (a_f + eps) (>= 0: the
        vehicle's body stays clear of the failed vehicle's no-fly cylinder a_f).
    cem.clearance_holds: min_actual_clearance >= 0 (healthy-to-failed pairs against
        cem.clearance_bound = a_f + eps, m).
    cem.min_pair_distance / cem.min_pair_distance_commanded: min healthy pairwise x-y distance of
        actual / commanded positions; cem.pair_bound = 2 (delta + eps);
        cem.separation_holds: min_pair_distance >= pair_bound (the theorems' conclusion; measured,
        so the summary prints FAIL when it was not kept even where no precondition claimed it).
        With fewer than two healthy agents there is no pair: the min is None, the key True, and the
        summary prints n/a (as for the theorems' preconditions then).
    cem.violations.separation.first_time / .agents, cem.violations.clearance.first_time / .agents:
        the first tick a healthy pair came closer than pair_bound (the pair), or a healthy agent came
        within a_f + eps of a failed vehicle (the healthy agents, then the failed ones); absent when
        the condition held.
    While CEM is active only:
    cem.max_speed / cem.max_speed_actual: peak 2-D commanded / actual speed of a healthy agent.
    cem.tracking_error_max: max x-y distance between a healthy agent and its command of that tick.
    cem.dphi_min: smallest sliding step of the run (Fig. 8). cem.step_ms_median: median wall time
        of one active ``adjust`` call, ms. cem.newton_iterations_mean: mean Newton iterations.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, model_validator

from swarmscene.methods.cem.mode import ContainmentExclusionMode, Settings
from swarmscene.plugin import (
    Avoidance,
    BuildContext,
    Event,
    PluginParams,
    Setpoints,
    WorldState,
    hookimpl,
    validate_renamed,
)

if TYPE_CHECKING:  # pragma: no cover
    from swarmscene.plugin import Sensing


class CEM(Avoidance):
    """Containment Exclusion Mode: healthy agents slide along streamlines around failed ones."""

    name = "cem"

    RENAMED_METRICS = {"cem.theorem1_holds": "cem.theorem1_precondition_met",
                       "cem.theorem2_holds": "cem.theorem2_precondition_met"}
    """Old key -> new key; metrics.json keeps both until the next release (docs/outputs.md lists them)."""

    class Params(PluginParams):
        """Options of ``avoidance=cem`` (defaults: the paper's section IV-V values)."""

        K: int = Field(2, ge=1, le=1000, description="sliding-step passes per tick (Alg. 1 line 14); "
                       "at most 1000 (the paper uses 1-5)")
        newton_iterations: int = Field(
            20, ge=1, le=1000, description="Newton iterations n of CalcXY (Alg. 2); at most 1000 (was n)")
        sigma: float = Field(1e-3, ge=0.0, description="saddle noise deviation, m (eq. 6)")
        saddle_noise: Literal["printed", "gated"] = Field(
            "printed", description="when CalcXY draws the eq. 6 noise: 'printed' in every Newton iteration whose "
            "estimate is within a_p (Alg. 2 as printed; the run depends on the seed), 'gated' only while the "
            "update is >= sigma and never in the last iteration (commands exactly on their streamlines, "
            "seed-independent)")
        newton_stop: Literal["fixed_n", "converged"] = Field(
            "fixed_n", description="when CalcXY's Newton loop stops: 'fixed_n' after newton_iterations every call "
            "(Algorithm 2 as printed); 'converged' once every update is below 1e-10 m with no noise drawn (the rule "
            "before: it changes the commands under printed noise, K = 1 peak 2.19 against 2.31 m/s)")
        branch_guard: bool = Field(
            True, description="move a command that converged inside a planned disk out through its circle, restart a "
            "non-finite one (a departure: not in the paper; without it 2 of 200 K = 2 runs of section V-A took "
            "the inner root and flew 6 cm from the failed vehicle)")
        multi_failure_flow: Literal["ring_streamlines", "unit_doublets", "summed"] = Field(
            "ring_streamlines", description="eq. 1 with several failures: 'ring_streamlines' one uniform term, "
            "doublet strengths that keep every a_p circle a streamline; 'unit_doublets' one uniform term, "
            "mu_f = a_p^2; 'summed' eq. 1's sum as printed (rings shrink towards a_p / sqrt(N_f)); "
            "identical for one failure")
        v_des: float = Field(1.0, gt=0.0, description="desired speed of the fastest agent, m/s")
        eps: float = Field(0.28, ge=0.0, description="vehicle enclosing radius epsilon, m")
        delta: float = Field(0.40, ge=0.0, description="bound on tracking error delta, m")
        a_f: float | None = Field(None, gt=0.0, description="failed vehicle's no-fly radius, m (None: eps + delta)")
        direction: float | Literal["auto"] = Field(
            "auto", description="flight direction, degrees from world +x counter-clockwise, or 'auto'"
        )
        hand_back: bool = Field(True, description="return control to the formation (see hand_back_rule); false: "
                                "CEM keeps control to the end of the run")
        hand_back_rule: Literal["clear_path", "passed"] = Field(
            "clear_path", description="when CEM hands control back (the paper is silent): 'clear_path' once every "
            "agent is handback_distance past the last failure and every formation setpoint, and the straight path "
            "to it, is at least a_p from every failed vehicle (re-activating CEM if one later comes closer); "
            "'passed' on the along-track test alone (the rule before; can hand back into a failed vehicle)")
        handback_distance: float | None = Field(
            None, gt=0.0, description="along-track distance past the last failure to hand back, m (None: 2 a_p)"
        )

        @model_validator(mode="wrap")
        @classmethod
        def _deprecated_n(cls, data: Any, handler: Any) -> Any:
            """``n`` (the paper's symbol, easily read as swarm.n) works for one release, with a warning."""
            return validate_renamed(data, handler, {"n": "newton_iterations"}, "avoidance")

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        p = self.params
        settings = Settings(
            K=p.K, newton_iterations=p.newton_iterations, sigma=p.sigma, saddle_noise=p.saddle_noise,
            newton_stop=p.newton_stop, branch_guard=p.branch_guard, multi_failure_flow=p.multi_failure_flow,
            v_des=p.v_des, eps=p.eps, delta=p.delta, a_f=p.a_f if p.a_f is not None else p.eps + p.delta,
            direction=p.direction, hand_back=p.hand_back, hand_back_rule=p.hand_back_rule,
            handback_distance=p.handback_distance)
        self.mode = ContainmentExclusionMode(ctx.n, settings, ctx.guidance_period, ctx.rng)

    @hookimpl
    def swarmscene_event(self, sim: Any, event: Event) -> None:
        """A ``hover`` or ``motor_failure`` adds its vehicles as doublets and (re)activates CEM.

        A vehicle that lost a rotor falls or spins down about the point where it failed, which the
        containment disk (in the x-y plane, over all altitudes) covers as it covers a hovering
        one. ``stuck`` and ``drift`` vehicles keep moving: the paper's Assumption 3 (a failed
        vehicle holds its position) does not hold for them, so CEM does not model them; they are
        still failed (``healthy`` False) for every other method and for the monitors.
        """
        if event.behaviour.stays_where_failed:  # hover, motor_failure: the kind says so
            self.mode.fail(event.agents, sim.world)

    def adjust(self, world: WorldState, sensing: Sensing, sp: Setpoints) -> Setpoints:
        """Pass ``sp`` through while inactive; else TRACK setpoints along the streamlines."""
        return self.mode.command(world, sp)

    @hookimpl
    def swarmscene_step_end(self, sim: Any) -> None:
        """Record the safety quantities of this tick, from the first activation to the end of the run."""
        self.mode.measure(sim.world)

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Add the ``cem.*`` metrics (see module docstring)."""
        metrics.update(self.metrics())

    def metrics(self) -> dict[str, Any]:
        """The ``cem.*`` metrics of the run so far (JSON-serialisable, None for undefined), with the
        old names of :data:`RENAMED_METRICS` beside the new ones until the next release."""
        metrics = self.mode.metrics()
        return {**metrics, **{old: metrics[new] for old, new in self.RENAMED_METRICS.items()}}

    @staticmethod
    def describe_verdict(key: str, m: dict[str, Any]) -> str | None:
        """The limit and scope of a ``cem.*`` verdict for the run summary (swarmscene/views/summary.py, which
        appends the first violation); ``"n/a: ..."`` where the run gives the check nothing to check."""
        def f(x: Any) -> str:
            return "n/a" if x is None else f"{x:.3g}"

        if key.startswith("cem.") and not m.get("cem.activations"):
            return "n/a: CEM never activated (no vehicle failed)"
        if key == "cem.separation_holds":
            if m["cem.min_pair_distance"] is None:
                return "n/a: fewer than two healthy agents, no pair to measure"
            text = (f"healthy pairs min {f(m['cem.min_pair_distance'])} m vs 2 (delta + eps) = "
                    f"{f(m['cem.pair_bound'])} m, x-y, from the first activation to the end of the run")
            if m["cem.theorem1_precondition_met"] or m["cem.theorem2_precondition_met"]:
                return text + " (the theorems' conclusion)"
            # measured all the same (FAIL when it was not kept), but no theorem promised it in this run
            return text + ("; the theorems' bound, not claimed here (no theorem's precondition met); the "
                           "separation line above is the scenario's own limit")
        if key == "cem.clearance_holds":
            gap = m["cem.min_actual_clearance"]
            if gap is None:
                return "n/a: no healthy agent measured against a failed vehicle"
            return (f"healthy to failed vehicles min {f(gap + m['cem.clearance_bound'])} m "
                    f"vs a_f + eps = {f(m['cem.clearance_bound'])} m, x-y, from the first activation to the end "
                    "of the run")
        if key == "mission" and m.get("cem.handback_time") is None and m.get("cem.handback_blocked_time") is not None:
            return (f"CEM kept control from {f(m['cem.handback_blocked_time'])} s: a formation setpoint, or the "
                    "path to it, lay within a_p of a failed vehicle (hand_back_rule=clear_path: the agents "
                    "stay safe but do not return to the formation)")
        if key == "cem.theorem1_precondition_met":
            if m["cem.theorem1_lhs"] is None:
                return "n/a: Theorem 1 (eq. 7-8) bounds pairs of healthy agents: fewer than two"
            return (f"Theorem 1 (eq. 7-8), p_min0^2 / lambda_max {f(m['cem.theorem1_lhs'])} vs 4 (delta + eps)^2 = "
                    f"{f(m['cem.theorem1_rhs'])} m^2 at every activation"
                    + ("" if m["cem.theorem1_precondition_met"] else
                       "; its guarantee is not claimed (it is conservative), the separation above is measured"))
        if key == "cem.theorem2_precondition_met":
            if not m.get("cem.theorem2_applicable"):
                return "n/a: Theorem 2 covers one failed vehicle at every activation"
            if m["cem.theorem2_d_min0"] is None:
                return "n/a: Theorem 2 (eq. 16) bounds pairs of healthy agents: fewer than two"
            return (f"Theorem 2 (eq. 16), d_min0 {f(m['cem.theorem2_d_min0'])} m vs 2 (delta + eps) + a_p = "
                    f"{f(m['cem.theorem2_bound'])} m at every activation"
                    + ("" if m["cem.theorem2_precondition_met"] else
                       "; its guarantee is not claimed, the separation above is measured"))
        return None


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`CEM` to the registry, so that ``avoidance=cem`` chooses it."""
    register(CEM)
