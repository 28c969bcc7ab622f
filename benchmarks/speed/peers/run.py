"""Every peer comparison in one command, one core, alternating: figures, ratios, goals.

    python benchmarks/speed/peers/run.py                       # everything (about 25 minutes)
    python benchmarks/speed/peers/run.py --quick               # a short smoke run of everything
    python benchmarks/speed/peers/run.py --only crazyflow,boids

Sections (``--only``): ``crazyflow`` (quadrotor swarms at 240 Hz and the time from command to first
result, bench_crazyflow.py), ``pybullet`` (whether gym-pybullet-drones installs from the package
index), ``boids`` (the flocking preset beside boids_numpy.py and Mesa, bench_boids.py), ``vmas``
(environment steps beside VMAS, bench_vmas.py), ``cem_cpp`` (bench_cem_cpp.py, when present).

The first run builds each peer's own virtual environment under ``benchmarks/speed/peers/.venv-<name>/``
from PyPI (git ignores them); nothing of a peer enters the repository. Every measurement is a fresh
process pinned to one core (``--core``, ``taskset``) with one thread (BLAS, OpenMP, XLA), the
compared sides alternating and each side's fastest run kept. Writes
``benchmarks/speed/results/peers.json`` (every figure, the commit, the load) and
``benchmarks/speed/results/peers.md`` (the section for docs/benchmarks.md), and prints the latter.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import peerlib
from peerlib import HERE, ROOT, child_json, load_average

SECTIONS = ("crazyflow", "pybullet", "boids", "vmas", "cem_cpp")
RESULTS = HERE.parent / "results"  # benchmarks/speed/results/
COMMAND = "python benchmarks/speed/peers/run.py"


# -- the sections -----------------------------------------------------------------------
def run_crazyflow(quick: bool, repeat: int) -> dict:
    """The Crazyflow section: steady-state and first-result figures, and the requirements installed."""
    import bench_crazyflow

    return {"steady": bench_crazyflow.steady(quick, repeat),
            "first": bench_crazyflow.first_result(quick, repeat),
            "requirements": bench_crazyflow.REQUIREMENTS}


def run_pybullet(quick: bool, repeat: int) -> dict:
    """gym-pybullet-drones from the package index, as a user would install it (pybullet for contrast)."""
    found = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("gym-pybullet-drones", "pybullet"):
            proc = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d", tmp, name],
                                  capture_output=True, text=True)
            lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("ERROR")]
            found[name] = {"installable": proc.returncode == 0,
                           "pip": lines[-1] if lines else "downloaded"}
    ok = found["gym-pybullet-drones"]["installable"]
    line = ("gym-pybullet-drones: on the package index (not measured here: no comparison written yet)" if ok else
            "gym-pybullet-drones: not on the package index (`pip download gym-pybullet-drones`: "
            f"{found['gym-pybullet-drones']['pip']}); pybullet itself is "
            f"({'downloadable' if found['pybullet']['installable'] else 'not downloadable either'}): not compared")
    print("  " + line)
    return {"packages": found, "line": line}


def run_boids(quick: bool, repeat: int) -> dict:
    """The boids section (bench_boids.py's comparison)."""
    import bench_boids

    return bench_boids.compare(quick, repeat)


def run_vmas(quick: bool, repeat: int) -> dict:
    """The VMAS section: best steps/s of each case per size (navigation only up to N = 100)."""
    import bench_vmas

    rows = []
    sizes = [(10, 100), (100, 40)] if quick else [(10, 500), (100, 100), (1000, 20)]
    version = "?"
    for n, steps in sizes:
        # VMAS navigation at N = 1,000 takes about a minute per step: left to bench_vmas.py itself.
        cases = {"simple", "parallel", "gym"} | ({"navigation"} if n <= 100 else set())
        best, version = bench_vmas.measure(n, steps, repeat, cases)
        rows.append({"n": n, "steps": steps, **best})
        print(f"  VMAS N = {n:,}: " + ", ".join(f"{bench_vmas.NAMES[k]} {v:.3g}" for k, v in best.items()) + " steps/s")
    return {"rows": rows, "vmas_version": version, "requirements": bench_vmas.VMAS_REQUIREMENTS}


def run_cem_cpp(quick: bool, repeat: int) -> dict:
    """The CEM C++ reference's own script (another helper's), run as a child with ``--json``."""
    script = HERE / "bench_cem_cpp.py"
    if not script.exists():
        print("  bench_cem_cpp.py: not present, skipped")
        return {"skipped": "benchmarks/speed/peers/bench_cem_cpp.py not present"}
    argv = ["--json"] + (["--rounds", "3"] if quick else [])
    return {"argv": argv, "result": child_json([sys.executable, str(script), *argv], timeout=3600)}


RUNNERS = {"crazyflow": run_crazyflow, "pybullet": run_pybullet, "boids": run_boids, "vmas": run_vmas,
           "cem_cpp": run_cem_cpp}


# -- the record -------------------------------------------------------------------------
def git(*args: str) -> str:
    """The output of a git command run in the repository (empty when it fails)."""
    proc = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return proc.stdout.strip()


def provenance() -> dict:
    """Where and when the figures were measured: commit, date, CPU, Python, the pinned core."""
    cpu = platform.processor()
    if Path("/proc/cpuinfo").exists():
        cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                    if ln.startswith("model name")), cpu)
    return {"commit": git("rev-parse", "--short", "HEAD"),
            "uncommitted_changes": bool(git("status", "--porcelain", "--untracked-files=no")),
            "date_utc": datetime.now(UTC).strftime("%Y-%m-%d %H:%M"),
            "cpu": cpu, "python": platform.python_version(), "core": peerlib.CORE,
            "one_thread_env": peerlib.ONE_THREAD}


# -- the markdown ----------------------------------------------------------------------
def fmt_rate(x: float | None) -> str:
    """A rate for the tables: three significant digits, thousands separated from 100, ``-`` when missing."""
    if x is None:
        return "-"
    if x >= 1e5:
        return f"{x:.3g}".replace("e+0", "e").replace("e+", "e")
    return f"{x:,.0f}" if x >= 100 else f"{x:.3g}"


def fmt_ratio(x: float | None) -> str:
    """A ratio for the tables (``2.35x``, one decimal from 10x), ``-`` when missing."""
    if x is None:
        return "-"
    return f"{x:.2f}x" if x < 10 else f"{x:.1f}x"


def verdict(ratio: float | None, goal: float) -> str:
    """The goal cell of a ratio: whether it reaches ``goal``, or that it was not measured."""
    if ratio is None:
        return f">= {goal:g}x: not measured"
    return f">= {goal:g}x: {'met' if ratio >= goal else 'not met'}"


def fmt_seconds(x: float | None) -> str:
    """Seconds for the tables, ``failed`` when the run gave none."""
    return "failed" if x is None else f"{x:.2f}"


def within(x: float | None, goal: float) -> str:
    """The goal cell of a time: whether ``x`` seconds is within ``goal``, or that it was not measured."""
    return f"<= {goal:g} s: " + ("not measured" if x is None else "met" if x <= goal else "not met")


def md_crazyflow(sec: dict) -> list[str]:
    """The Crazyflow section in markdown: the steady-state table and the time to the first result."""
    steady, first = sec["steady"], sec["first"]
    default = first["crazyflow_detail"].get("crazyflow_default", {})
    goals_default = {100: 1.5, 1000: 1.2}
    out = ["### Quadrotor swarms hovering, physics at 240 Hz, beside Crazyflow (issue #20)", "",
           f"`{COMMAND} --only crazyflow` (Crazyflow {default.get('version', '0.4.0')}, "
           f"JAX {default.get('jax', '?')} CPU, in "
           "`benchmarks/speed/peers/.venv-crazyflow`; bench_crazyflow.py). N drones 2 m apart at 2 m, each holding "
           "its point under state control, physics at 240 Hz, the position command at 10 Hz (the engine's "
           "default guidance period, T_s = 0.1 s; Crazyflow `state_freq=10`, 24 physics steps per command) "
           "or at 240 Hz (a command every physics step). Drone-steps/s (physics steps) in steady state "
           f"({steady['rows'][0]['warm']} physics steps of warm-up, then {steady['rows'][0]['steps']} timed), "
           f"best of {steady['repeat']} alternated runs:", "",
           "| command rate | N | swarmscene (whole tick, monitor on) | Crazyflow default (Euler, float32) "
           "| ratio | goal | Crazyflow RK4 float64 | ratio | goal | Crazyflow fused `step(K)`: default / RK4 float64 |",
           "|---:|---:|---:|---:|---:|---|---:|---:|---|---:|"]
    failures = []
    for row in steady["rows"]:
        n = row["n"]
        rate = {side: (fmt_rate(row[side]["drone_steps_per_s"]) if "error" not in row[side] else "failed")
                for side in ("swarmscene", "crazyflow_default", "crazyflow_rk4_f64")}
        fused = {side: fmt_rate(row[side].get("fused_drone_steps_per_s"))
                 for side in ("crazyflow_default", "crazyflow_rk4_f64")}
        failures += [f"N = {n:,}, {side}: {row[side]['error']}" for side in rate if "error" in row[side]]
        g = goals_default.get(n)
        rd, rr = row.get("ratio_default"), row.get("ratio_rk4_f64")
        out.append(f"| {row.get('command_hz', 240)} Hz | {n:,} | {rate['swarmscene']} "
                   f"| {rate['crazyflow_default']} | {fmt_ratio(rd)} | {verdict(rd, g) if g else '-'} "
                   f"| {rate['crazyflow_rk4_f64']} | {fmt_ratio(rr)} | {verdict(rr, 2.0)} | "
                   f"{fused['crazyflow_default']} / {fused['crazyflow_rk4_f64']} |")
    out += ["", "Failed runs: " + "; ".join(failures) + "."] if failures else []
    s = first["seconds"]
    det = first["crazyflow_detail"].get("crazyflow_default", {})
    nan = float("nan")
    out += ["", f"Time from command to first result, N = {first['n']:,} (wall time of a fresh process until it exits "
            f"after its first simulated step, best of {first['repeat']}):", "",
            "| | seconds | goal |", "|---|---:|---|",
            f"| swarmscene, numba cache warm | {fmt_seconds(s.get('swarmscene_warm'))} "
            f"| {within(s.get('swarmscene_warm'), 2)} |",
            f"| swarmscene, numba cache cold (empty `NUMBA_CACHE_DIR`) | {fmt_seconds(s.get('swarmscene_cold'))} | "
            f"{within(s.get('swarmscene_cold'), 8)} |",
            f"| Crazyflow default (no persistent cache: import {det.get('import_s', nan):.1f} s, `Sim` built "
            f"{det.get('build_s', nan):.1f} s, first `step(1)` with JIT {det.get('first_step_s', nan):.1f} s) "
            f"| {fmt_seconds(s.get('crazyflow_default'))} | - |",
            f"| Crazyflow with its persistent JAX cache warm (`crazyflow.utils.enable_cache`) | "
            f"{fmt_seconds(s.get('crazyflow_cached'))} | - |"]
    if first.get("errors"):
        out += ["", "Failed: " + "; ".join(f"{k}: {v}" for k, v in first["errors"].items()) + "."]
    out += [
        "", f"The swarmscene command: `{first['swarmscene_command']}`.", "",
        "What each side does per tick. swarmscene, the whole engine tick through `swarmscene.api` (the "
        "command's overrides; the start given explicitly as the formation's grid slots, see below): events, "
        "the sensing snapshot, the formation's setpoints (`static_shape` holding its grid), the SE(3) "
        "controller, rotor mixer and one RK4 step of each 6-DOF body in float64, the safety monitor "
        "(separation, connectivity), the hooks; timed by the engine (`step_seconds`). Crazyflow: "
        "`Sim(n_worlds=1, n_drones=N, control=Control.state, freq=240, state_freq=R, attitude_freq=240)` "
        "(its cf21B_500 drone, first-principles dynamics with rotor dynamics, Mellinger state and attitude "
        "controllers), per tick `sim.state_control(cmd)` then `sim.step(240 // R)`, the command re-sent and "
        "nothing read back; `default` is its Euler integrator in float32, `RK4 float64` sets "
        "`integrator=Integrator.rk4` and `jax_enable_x64`. The fused column advances K steps in one jitted "
        "`sim.step(K)` with the command held: Crazyflow at its fastest, with no guidance between steps (no "
        "goal). The goals are judged at the engine's default 10 Hz guidance; the 240 Hz rows show the fixed "
        "cost of a guidance tick (formation, sensing, monitor, hooks) paid at every physics step.", "",
        "Both sides hold the same points: `static_shape`'s grid slots, 2 m apart at 2 m (for N = 1 and 100 "
        "the points of `swarm=grid`; at N = 1,000 `swarm=grid` puts its short row on the other side from the "
        "formation's, and those agents would cross the swarm, so the steady runs start on the slots). What "
        "differs: Crazyflow's step has no sensing, no neighbour query and no safety monitor; swarmscene's "
        "drones start at rest in equilibrium at their point, Crazyflow's with their rotors still (they sag a "
        "few centimetres and recover during the warm-up); the cost of neither depends on the state."]
    return out


def md_pybullet(sec: dict) -> list[str]:
    """The gym-pybullet-drones section in markdown: why it has no figures."""
    return ["### gym-pybullet-drones", "", sec["line"] + ". Its README installs it from a clone of its "
            "repository (`git clone ...` then `pip3 install -e .`, pybullet compiled from source beyond Python "
            "3.10); these comparisons take peers from the package index only, so it is not built from a "
            "fetched source tree and has no figures here.", ""]


def md_boids(sec: dict) -> list[str]:
    """The boids section in markdown: the table and how each side is built."""
    p = sec["params"]
    out = ["### Boids beside a numpy reference and Mesa (issue #20)", "",
           f"`{COMMAND} --only boids` (bench_boids.py; Mesa {sec.get('mesa_version') or '?'} in "
           "`benchmarks/speed/peers/.venv-mesa`). `scenario=flocking` with the preset's parameters (vision "
           f"{p['vision']:g} m, separation {p['separation']:g} m, weights {p['cohere']:g} / {p['separate']:g} / "
           f"{p['match']:g}, {p['speed'] * p['dt']:g} m per {p['dt']:g} s step, kinematic points with u_max "
           f"{p['u_max']:g} m/s, comm.range {p['comm_range']:g} m, separation limit {p['separation_limit']:g} m) "
           "in a torus of side L (`formation.box_max`), all sides from the same start (Mesa's draws, seed 0). "
           f"Steps/s over the steps after the first {sec['warm_steps']}, best of {sec['repeat']} alternated runs:", "",
           "| N | L (m) | steps | swarmscene | numpy reference | ratio | goal | Mesa (steps) | ratio | goal | "
           "polarization swarmscene / numpy / Mesa |",
           "|---:|---:|---:|---:|---:|---:|---|---:|---:|---|---|"]
    for row in sec["rows"]:
        ours, ref = row["swarmscene"], row["numpy"]
        mesa = row.get("mesa")
        goal_ref = verdict(row["ratio_numpy"], 1.5) if row["note"] == "preset density" else "-"
        mesa_cells = (f"{fmt_rate(mesa['steps_per_s'])} ({row['mesa_steps']}) | {fmt_ratio(row['ratio_mesa'])} | "
                      f"{verdict(row['ratio_mesa'], 30) if row['note'] == 'preset density' else '-'}"
                      if mesa else "- | - | -")
        pol = (f"{ours['polarization']:.4f} / {ref['polarization']:.4f} / "
               + (f"{mesa['polarization']:.4f}" if mesa else "-"))
        box = f"{row['box_m']:.0f}{'' if row['note'] == 'preset density' else ' (Mesa default)'}"
        out.append(f"| {row['n']:,} | {box} | "
                   f"{row['steps']} | {fmt_rate(ours['steps_per_s'])} | {fmt_rate(ref['steps_per_s'])} | "
                   f"{fmt_ratio(row['ratio_numpy'])} | {goal_ref} | {mesa_cells} | {pol} |")
    gaps = ", ".join(f"{r['polarization_gap']:.1e}" for r in sec["rows"])
    same = all(r["swarmscene"][k] == r["numpy"][k] for r in sec["rows"] for k in ("collisions", "connected"))
    sep_gap = max(abs(r["swarmscene"]["min_separation"] - r["numpy"]["min_separation"])
                  / r["numpy"]["min_separation"] for r in sec["rows"])
    out += ["", f"swarmscene and the reference end with the same polarization (differences {gaps}, round-off of "
            "the sums' order) and the same monitor's figures: distinct colliding pairs and connectivity "
            + ("equal on every row" if same else "DIFFERENT on some row (see peers.json)")
            + f", the smallest separation within {sep_gap:.1e} relative (the same round-off, carried along the "
            "flight).", "",
            "The sides: swarmscene runs `scenario=flocking swarm.n=N formation.box_max=[L,L,L]` with the explicit "
            "start through `swarmscene.api` (the whole tick timed by the engine: sensing, the flock, the "
            "kinematic points, the torus wrap, the safety monitor, the hooks). `benchmarks/speed/peers/boids_numpy.py` "
            "is the same rule written in plain numpy and scipy (no swarmscene): per step one `cKDTree` and one "
            "`query_pairs` at the comm range, shared by the flock (filtered to vision, the torus' seam pairs from "
            "the images of the boids near a face) and its monitor (smallest distance, colliding pairs, "
            "`connected_components` of the pairs within comm range, exact every step), each pair feeding both ends "
            "through `np.bincount`; swarmscene's monitor reaches the same verdicts by its own means. "
            "Mesa's `BoidFlockers` (bench_mesa.py's child) moves its boids one at a time in random "
            "order and has no monitor; at N = 10,000 it is not run (its cost grows as N^2).", "",
            "L = 10 sqrt(N) m is the preset's density (100 boids per 100 m x 100 m, as its comment scales "
            "it); the last row keeps Mesa's default 100 m box at N = 1,000 (ten times denser: more "
            "neighbours per boid: more work for swarmscene and the reference, little more for Mesa, whose "
            "boids each measure their distance to every other boid in any box)."]
    return out


def md_vmas(sec: dict) -> list[str]:
    """The VMAS section in markdown: steps/s of each case per size."""
    import bench_vmas

    keys = list(bench_vmas.NAMES)
    out = ["### Environment steps beside VMAS", "",
           f"`{COMMAND} --only vmas` (bench_vmas.py's cases; VMAS {sec['vmas_version']}, "
           f"{sec['requirements'][0]} CPU, one thread; `navigation` at N = 1,000 takes about a minute a step and "
           "is left to bench_vmas.py). Environment steps/s of one environment:", "",
           "| N | steps | " + " | ".join(bench_vmas.NAMES[k] for k in keys) + " | ParallelEnv / VMAS simple |",
           "|---:|---:|" + "---:|" * (len(keys) + 1)]
    for row in sec["rows"]:
        cells = [fmt_rate(row.get(k)) for k in keys]
        ratio = fmt_ratio(row["parallel"] / row["simple"]) if "parallel" in row and "simple" in row else "-"
        out.append(f"| {row['n']:,} | {row['steps']} | " + " | ".join(cells) + f" | {ratio} |")
    return out


def md_cem_cpp(sec: dict) -> list[str]:
    """The section of CEM beside its C++ reference in markdown (or why it was skipped)."""
    if "skipped" in sec:
        return ["### CEM beside its C++ reference", "", f"Skipped: {sec['skipped']}."]
    r = sec["result"]
    out = ["### CEM beside its C++ reference", "", f"`{COMMAND} --only cem_cpp` (bench_cem_cpp.py "
           f"{' '.join(sec['argv'])}, its own alternation and pinning):", ""]
    if not (isinstance(r, dict) and r.get("benchmark") == "cem_six_vehicle_step"):
        return out + ["```", json.dumps(r, indent=1), "```"]  # a format this runner does not know yet
    labels = {"cpp": f"C++ reference ({r.get('compiler', '?')})", "plugin": "swarmscene `CEM.adjust` (kernel)",
              "navigator": "swarmscene navigator step (kernel)", "numpy": "former NumPy step (oracle)"}
    cpu, wall = r["ms_per_step_cpu"], r["ms_per_step_wall"]
    out += [f"Section V-A six-vehicle manoeuvre, {r['ticks']} ticks, median of {r['rounds']} rounds; thread CPU "
            "time per tick (wall beside it):", "",
            "| | us/step CPU (wall) | / C++ CPU (wall) | goal |", "|---|---:|---:|---|"]
    for key, label in labels.items():
        if key not in cpu:
            continue
        ratio = "-" if key == "cpp" else (f"{fmt_ratio(r['ratio_to_cpp_cpu'][key])} "
                                          f"({fmt_ratio(r['ratio_to_cpp_wall'][key])})")
        goal = (f"<= {r['goal_ratio']:g}x: {'met' if r['ratio_to_cpp_cpu'][key] <= r['goal_ratio'] else 'not met'}"
                if key == "plugin" and "goal_ratio" in r else "-")
        out.append(f"| {label} | {cpu[key] * 1e3:.2f} ({wall[key] * 1e3:.2f}) | {ratio} | {goal} |")
    agree = r.get("agreement", {}).get("no_noise")
    if agree:
        out += ["", f"Same inputs, sigma = 0: C++ and swarmscene agree within {agree['max_abs_pos_m_no_draws']:.1e} m "
                f"on all {agree['ticks']:,} ticks (details in peers.json)."]
    return out


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "-" if value is None else str(value)


MARKDOWN = {"crazyflow": md_crazyflow, "pybullet": md_pybullet, "boids": md_boids, "vmas": md_vmas,
            "cem_cpp": md_cem_cpp}


def markdown(record: dict) -> str:
    """The page of every section measured, headed by how and where the figures were taken."""
    prov = record["provenance"]
    lines = ["## Side by side with peer simulators (issue #20)", "",
             f"`{record.get('command', COMMAND)}`"
             f"{' (a smoke run: short, one pass; not for the record)' if record['quick'] else ''}; "
             f"measured {prov['date_utc']} UTC at commit {prov['commit']}"
             f"{' with uncommitted changes in the tree' if prov['uncommitted_changes'] else ''}, {prov['cpu']}, "
             f"every process pinned to core {prov['core']} with one thread (BLAS, OpenMP; XLA "
             "`--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1`), the compared sides "
             f"alternating, each side's fastest run kept; load average {record['load_start']:.1f} at the start, "
             f"{record['load_end']:.1f} at the end ({record['wall_s'] / 60:.0f} min). Each peer in its own "
             "virtual environment under `benchmarks/speed/peers/.venv-<name>/`, built from PyPI on the first run.", ""]
    for name, section in record["sections"].items():
        if "error" in section:
            lines += [f"### {name}", "", f"Failed: {section['error']}", ""]
        else:
            lines += MARKDOWN[name](section) + [""]
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> None:
    """Run the chosen sections (one failing keeps the others' figures) and write peers.json and peers.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short smoke run: fewer steps, one pass")
    parser.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated subset of {', '.join(SECTIONS)}")
    parser.add_argument("--repeat", type=int, default=3, help="alternations; each side's fastest run counts")
    parser.add_argument("--core", type=int, default=1, help="the core every child is pinned to")
    parser.add_argument("--out", type=Path, default=RESULTS, help="folder for peers.json and peers.md")
    args = parser.parse_args(argv)
    chosen = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [s for s in chosen if s not in SECTIONS]
    if unknown:
        parser.error(f"--only: unknown section(s) {', '.join(unknown)} (choose from {', '.join(SECTIONS)})")
    peerlib.CORE = args.core
    repeat = 1 if args.quick else args.repeat
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    record = {"command": f"{COMMAND} {shown}".strip(), "quick": args.quick, "repeat": repeat,
              "load_start": load_average(), "provenance": provenance(), "sections": {}}
    start = time.perf_counter()
    for name in chosen:
        print(f"{name}:", flush=True)
        try:
            record["sections"][name] = RUNNERS[name](args.quick, repeat)
        except Exception as exc:  # one peer failing must not lose the others' figures
            print(f"  {name} failed: {exc}", flush=True)
            record["sections"][name] = {"error": str(exc).splitlines()[0] if str(exc) else type(exc).__name__,
                                        "detail": str(exc)}
    record["wall_s"] = time.perf_counter() - start
    record["load_end"] = load_average()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "peers.json").write_text(json.dumps(record, indent=1) + "\n")
    text = markdown(record)
    (args.out / "peers.md").write_text(text)
    print()
    print(text)


if __name__ == "__main__":
    main()
