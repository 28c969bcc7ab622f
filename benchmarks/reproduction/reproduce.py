"""The reproduction report: every paper number a shipped scenario reproduces, for each reading.

    python benchmarks/reproduction/reproduce.py                    # all claims -> docs/reproduction.md
    python benchmarks/reproduction/reproduce.py --only cem         # claims whose id or paper contains "cem"
    python benchmarks/reproduction/reproduce.py --jobs 2 --cache /tmp/repro   # resume an interrupted run

The claims are declared in ``benchmarks/reproduction/claims/*.yaml`` (format:
``benchmarks/reproduction/claims/README.md``): the paper's value, where it is printed, the scenario
and metric that reproduce it, how many seeds, and every reading of the paper the number depends on
(the first is the default, literal one). Each (run overrides, seed) is run once however many claims
read it; runs go to ``--jobs`` worker processes. A rate (a boolean metric) gets its 95 % Wilson
interval, any other number the mean's 95 % Student-t interval; a claim whose runs are identical over
seeds is marked deterministic.

Verdicts: a claim "=" holds when ``|mean - paper| <= tolerance`` (a one-flight figure,
``one_run``: when at least half the seeds are within tolerance); a bound ("<=", ">=") when the
worst seed is within ``tolerance`` of it (a paper bound holds "throughout", so every seed must
meet it). Separately the table says whether our interval contains the paper's value, and the
report lists every claim where it does not, with the claim's note on why.

``tests/test_reproduction.py`` (marked slow) re-runs the default reading of each claim and asserts
its verdict: within tolerance, or, for a claim declared ``expect: misses`` (the literal reading
is known not to reach the paper's text; its note says why), still outside it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, model_validator

from swarmscene.sweeps.stats import lower_bound, mean_interval, wilson

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]  # benchmarks/reproduction/ -> the repository
CLAIMS_DIR = HERE / "claims"
FUNCTIONS_DIR = HERE.relative_to(ROOT).as_posix()
"""Where a function claim's module (``fig_thesis:gain``) lives, as the report's commands name it."""
DEPARTURES = CLAIMS_DIR / "departures.yaml"
"""Where the shipped defaults depart from the papers as printed (not claims: the report's table)."""
PAPERS = {
    "cem": "Romano et al., fluid-flow CEM navigation (../shared/papers/cem-fluid-flow-navigation.md)",
    "vrb": "Zhou and Schwager, Virtual Rigid Bodies (../shared/papers/virtual-rigid-bodies.md)",
    "thesis": "Karydes (2020), quadrotor swarms thesis (../shared/papers/quadrotor-swarms-thesis.md)",
}
QUIET = ["output.trajectory=false", "output.summary=false", "output.progress=off"]
TAIL_SEEDS = 10
"""From this many seeds, a Student-t interval that reaches past every value observed is a heavy tail
(one seed far from the others), and the interval is the percentile bootstrap's instead."""


class Claim(BaseModel):
    """One number printed in a paper and the runs that reproduce it (see claims/README.md)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str
    paper: Literal["cem", "vrb", "thesis"]
    where: str
    quantity: str
    paper_value: float
    relation: Literal["=", "<=", ">="] = "="
    tolerance: float = Field(0.0, ge=0)
    unit: str = ""
    overrides: list[str] = Field(default_factory=list)
    metric: str | None = None
    function: str | None = None
    seeds: int = Field(1, ge=1)
    reading_seeds: dict[str, int] = Field(default_factory=dict)
    readings: dict[str, list[str]] = Field(default_factory=lambda: {"as printed": []})
    note: str = ""
    expect: Literal["holds", "misses"] = "holds"
    printed: bool = True
    """False: the paper prints no such number; paper_value (and its tolerance) is our reading of the
    text or of a figure, marked in the report's paper column."""
    one_run: bool = False
    """The paper's number is one run (a figure of one flight): it is judged on the share of seeds
    that meet it (within tolerance for "="; at or above it for ">=", at or below for "<="), shown
    with its Wilson interval, never on the mean: an "=" claim holds when at least half the seeds
    are within tolerance, and "in interval" asks whether the paper's flight lies within the range
    of ours (bounds stay judged on every seed, as they hold "throughout")."""
    shipped: str | None = None
    """The reading the shipped scenario flies, when it is not the first (VRB's Fig. 8: the first
    reading is the paper's literal one, the show ships the calibrated side and gains); the report
    marks it in the reading column."""
    bounded: bool | None = None
    """The quantity cannot be negative (percentile-bootstrap interval, never below zero); None:
    decided by the metric's name (swarmscene.sweeps.stats.lower_bound), False for a function claim."""

    @model_validator(mode="after")
    def _renamed_metric(self) -> Claim:
        """A metric renamed this release still reads (metrics.json keeps the old key), with a warning."""
        new = renamed_metrics().get(self.metric or "")
        if new is not None:
            import warnings

            warnings.warn(f"{self.id}: metric {self.metric} is renamed {new} (the old key is kept in metrics.json "
                          "until the next release; docs/outputs.md)", DeprecationWarning, stacklevel=2)
        return self

    @model_validator(mode="after")
    def _one_source(self) -> Claim:
        if self.expect == "misses" and not self.note.strip():
            raise ValueError(f"{self.id}: expect: misses needs a note saying why the default reading misses")
        if (self.metric is None) == (self.function is None):
            raise ValueError(f"{self.id}: give either metric (with overrides) or function")
        if not self.readings:
            raise ValueError(f"{self.id}: readings: at least one (the default reading first)")
        if self.shipped is not None and self.shipped not in self.readings:
            raise ValueError(f"{self.id}: shipped: not one of its readings ({self.shipped!r})")
        unknown = set(self.reading_seeds) - set(self.readings)
        if unknown or self.default_reading in self.reading_seeds:
            raise ValueError(f"{self.id}: reading_seeds: only for readings other than the default "
                             f"(got {sorted(self.reading_seeds)})")
        return self

    def n_seeds(self, reading: str) -> int:
        """Seeds run for ``reading``: ``seeds``, or fewer for a non-default reading."""
        return self.reading_seeds.get(reading, self.seeds)

    @property
    def default_reading(self) -> str:
        """The first reading listed: the one the claim's ``expect`` and the report's verdict are about."""
        return next(iter(self.readings))

    def jobs(self, reading: str) -> list[Job]:
        """The runs this claim needs for one reading: one per seed."""
        extra = tuple(self.readings[reading])
        if self.function is not None:
            return [Job(function=self.function, args=extra, seed=s) for s in range(self.n_seeds(reading))]
        return [Job(overrides=(*self.overrides, *extra), seed=s) for s in range(self.n_seeds(reading))]

    def command(self, reading: str) -> str:
        """The command line that reproduces one run of this claim in this reading."""
        if self.function is not None:
            module, name = self.function.split(":")
            # The call run_job makes for seed 0: each of the reading's words one argument. From the
            # repository root, like every other command in the report; double quotes outside
            # because repr() quotes the arguments with single ones.
            call = f"{name}({', '.join(['0', *map(repr, self.readings[reading])])})"
            return f'PYTHONPATH={FUNCTIONS_DIR} python -c "from {module} import {name}; print({call})"'
        words = [*self.overrides, *self.readings[reading]]
        n = self.n_seeds(reading)
        seeds = f"seed='range(0,{n})' --multirun" if n > 1 else "seed=0"
        return " ".join(["swarmscene", *words, seeds])


def renamed_metrics() -> dict[str, str]:
    """Old metric key -> new key, from the plugins that renamed keys this release (``RENAMED_METRICS``)."""
    from swarmscene.plugins.avoidance.cem import CEM

    return dict(CEM.RENAMED_METRICS)


@dataclass(frozen=True)
class Job:
    """One run: a scenario's overrides and seed, or a function called with the seed."""

    overrides: tuple[str, ...] = ()
    function: str | None = None
    args: tuple[str, ...] = ()
    seed: int = 0

    @property
    def key(self) -> str:
        """The run's identity (a hash of overrides, function, arguments and seed), its file name in the cache."""
        text = json.dumps([self.overrides, self.function, self.args, self.seed])
        return hashlib.sha256(text.encode()).hexdigest()[:20]


def load_claims(directory: Path = CLAIMS_DIR) -> list[Claim]:
    """Every claim of every ``*.yaml`` in ``directory``, in file then list order."""
    claims: list[Claim] = []
    for path in sorted(directory.glob("*.yaml")):
        if path.name == DEPARTURES.name:
            continue
        for entry in yaml.safe_load(path.read_text()) or []:
            claims.append(Claim.model_validate(entry))
    ids = [c.id for c in claims]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ValueError(f"claim ids declared twice: {twice}")
    return claims


# -- running ------------------------------------------------------------------------------------
def run_job(job: Job) -> dict[str, Any]:
    """The metrics of one run (or ``{"value": f(seed)}`` for a function claim)."""
    if job.function is not None:
        if str(HERE) not in sys.path:
            sys.path.insert(0, str(HERE))
        module, name = job.function.split(":")
        func: Callable[..., float] = getattr(__import__(module, fromlist=[name]), name)
        value = func(job.seed, *job.args)
        return {"value": value if isinstance(value, bool) else float(value)}  # a bool: a rate
    from swarmscene import api

    result = api.run([*job.overrides, f"seed={job.seed}", *QUIET])
    return json.loads(json.dumps(result.metrics, default=str))


def _guarded(job: Job) -> dict[str, Any]:
    """:func:`run_job`, with a failure kept as ``{"error": line}`` (the claim then lacks a value
    and fails) instead of ending the whole report."""
    try:
        return run_job(job)
    except Exception as exc:  # noqa: BLE001 - any failure of one run is reported, not raised
        return {"error": f"{type(exc).__name__}: {exc}".splitlines()[0]}


def run_jobs(jobs: Iterable[Job], n_jobs: int = 1, cache: Path | None = None,
             progress: bool = True) -> dict[str, dict[str, Any]]:
    """Metrics of every distinct job, by :attr:`Job.key`; ``cache`` keeps each finished run as a
    JSON file so an interrupted report resumes (valid for one version of the code only)."""
    todo: dict[str, Job] = {job.key: job for job in jobs}
    done: dict[str, dict[str, Any]] = {}
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        for key in list(todo):
            path = cache / f"{key}.json"
            if path.exists():
                done[key] = json.loads(path.read_text())
                del todo[key]
    started, total = time.perf_counter(), len(todo)

    def finished(key: str, metrics: dict[str, Any], count: int) -> None:
        done[key] = metrics
        if cache is not None and "error" not in metrics:  # a failed run is retried next time
            (cache / f"{key}.json").write_text(json.dumps(metrics))
        if progress and (count % 10 == 0 or count == total):
            rate = count / (time.perf_counter() - started)
            left = (total - count) / rate if rate > 0 else math.nan
            print(f"\r{count}/{total} runs, {left / 60:.1f} min left ", end="", file=sys.stderr, flush=True)

    if n_jobs <= 1:
        for count, (key, job) in enumerate(todo.items(), 1):
            finished(key, _guarded(job), count)
    else:
        with ProcessPoolExecutor(max_workers=n_jobs) as pool:
            futures = {pool.submit(_guarded, job): key for key, job in todo.items()}
            for count, future in enumerate(as_completed(futures), 1):
                finished(futures[future], future.result(), count)
    if progress and total:
        print(file=sys.stderr)
    return done


# -- statistics ---------------------------------------------------------------------------------
@dataclass
class Outcome:
    """One claim in one reading: the per-seed values and what they say about the paper's number."""

    claim: Claim
    reading: str
    values: list[float]
    rate: bool = False
    mean: float = math.nan
    low: float = math.nan
    high: float = math.nan
    worst: float = math.nan
    deterministic: bool = False
    holds: bool = False
    contains_paper: bool = False
    missing: int = 0
    reach: int | None = None  # one-run claims: seeds at or above (<=: at or below) the paper's value
    run: str = ""  # the commit the runs were made at

    def as_dict(self) -> dict[str, Any]:
        """This outcome as a record of the JSON report."""
        return {
            "id": self.claim.id, "reading": self.reading, "n": len(self.values), "rate": self.rate,
            "mean": self.mean, "ci95": [self.low, self.high], "worst": self.worst,
            "deterministic": self.deterministic, "holds": self.holds,
            "interval_contains_paper": self.contains_paper, "missing": self.missing,
            "reach_paper": self.reach, "run": self.run, "values": self.values,
        }


def evaluate(claim: Claim, reading: str, results: dict[str, dict[str, Any]]) -> Outcome:
    """The outcome of ``claim`` in ``reading`` from the finished runs."""
    raw = [results[job.key].get(claim.metric or "value") for job in claim.jobs(reading)]
    return evaluate_values(claim, reading, raw)


def bounded(claim: Claim) -> bool:
    """Whether the claim's quantity cannot be negative (its interval is the percentile bootstrap)."""
    if claim.bounded is not None:
        return claim.bounded
    return claim.metric is not None and lower_bound(claim.metric) is not None


def evaluate_values(claim: Claim, reading: str, raw: list[Any], run: str = "") -> Outcome:
    """The outcome of ``claim`` in ``reading`` from its per-seed values (None: the run gave none)."""
    rate = all(isinstance(v, bool) for v in raw if v is not None) and any(v is not None for v in raw)
    values = [float(v) for v in raw if v is not None]
    out = Outcome(claim, reading, values, rate=rate, missing=len(raw) - len(values), run=run)
    if not values:
        return out
    x = np.asarray(values)
    out.mean = float(x.mean())
    # A rate of all-successes is not a deterministic scenario: only numbers can tell.
    out.deterministic = not rate and len(x) > 1 and bool(np.all(x == x[0]))
    if rate:
        out.low, out.high = wilson(int(x.sum()), len(x))
    elif len(x) > 1 and not out.deterministic:
        tail = len(x) >= TAIL_SEEDS  # fewer: t's width past the values is the sample's size, not a tail
        _, out.low, out.high, _ = mean_interval(values, bounded=bounded(claim), within_values=tail)
    else:
        out.low = out.high = out.mean
    rel, paper, tol = claim.relation, claim.paper_value, claim.tolerance
    if claim.one_run and not rate:  # the paper's number is one run: how many of ours meet it
        met = {"=": np.abs(x - paper) <= tol + 1e-12, "<=": x <= paper + 1e-12, ">=": x >= paper - 1e-12}[rel]
        out.reach = int(met.sum())
    if rel == "=" and out.reach is not None:  # one flight: judged on the share of seeds, not the mean
        out.worst = float(x.max() if abs(x.max() - paper) > abs(x.min() - paper) else x.min())
        out.holds = 2 * out.reach >= len(x) and out.missing == 0
        out.contains_paper = bool(x.min() - 1e-12 <= paper <= x.max() + 1e-12)
    elif rel == "=":
        out.worst = float(x.max() if abs(x.max() - paper) > abs(x.min() - paper) else x.min())
        out.holds = abs(out.mean - paper) <= tol + 1e-12 and out.missing == 0
        out.contains_paper = out.low - 1e-12 <= paper <= out.high + 1e-12
    elif rel == "<=":
        out.worst = float(x.max())
        out.holds = out.worst <= paper + tol + 1e-12 and out.missing == 0
        out.contains_paper = out.worst <= paper + 1e-12
    else:
        out.worst = float(x.min())
        out.holds = out.worst >= paper - tol - 1e-12 and out.missing == 0
        out.contains_paper = out.worst >= paper - 1e-12
    return out


def kept_outcomes(path: Path, claims: list[Claim], label: str | None = None) -> dict[tuple[str, str], Outcome]:
    """Outcomes stored in an earlier report's JSON (``--keep``), re-evaluated under today's claim
    definitions (intervals, marks); keyed by (claim id, reading). Each keeps where its runs came from."""
    stored = json.loads(path.read_text())
    default_run = label or stored.get("meta", {}).get("commit", "earlier")
    by_id = {c.id: c for c in claims}
    out = {}
    for entry in stored.get("outcomes", []):
        claim = by_id.get(entry.get("id"))
        if claim is None or entry.get("reading") not in claim.readings:
            continue
        raw: list[Any] = [bool(v) if entry.get("rate") else v for v in entry.get("values", [])]
        raw += [None] * int(entry.get("missing", 0))
        run = entry.get("run") or default_run
        out[(claim.id, entry["reading"])] = evaluate_values(claim, entry["reading"], raw, run)
    return out


# -- the report ---------------------------------------------------------------------------------
def _num(value: float, rate: bool, unit: str) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    if rate:
        return f"{100 * value:.1f} %"
    return f"{value:.4g}" + (f" {unit}" if unit else "")


def _ours(o: Outcome) -> str:
    c = o.claim
    if not o.values:
        return "no value"
    if o.deterministic or len(o.values) == 1:
        return f"{_num(o.mean, o.rate, c.unit)} (det.)" if o.deterministic else _num(o.mean, o.rate, c.unit)
    if o.rate:
        return f"{100 * o.mean:.1f} % [{100 * o.low:.1f}, {100 * o.high:.1f}]"
    text = f"{o.mean:.4g} [{o.low:.4g}, {o.high:.4g}]" + (f" {c.unit}" if c.unit else "")
    if o.reach is not None:  # one run in the paper: the share of our seeds that meet its value
        low, high = wilson(o.reach, len(o.values))
        side = {"=": "within tolerance of", "<=": "≤", ">=": "≥"}[c.relation]
        text += (f"; {side} paper in {o.reach} of {len(o.values)} seeds "
                 f"({100 * o.reach / len(o.values):.1f} % [{100 * low:.1f}, {100 * high:.1f}])")
    return text


def _verdict(o: Outcome) -> str:
    if o.holds:
        return "yes"
    known = o.claim.expect == "misses" and o.reading == o.claim.default_reading
    return "no (known, see below)" if known else "**no**"


def _paper(c: Claim, rate: bool) -> str:
    """The paper's number as it reads (a bound with its sign); † where it is our reading of the text."""
    rel = {"=": "", "<=": "≤ ", ">=": "≥ "}[c.relation]
    return rel + _num(c.paper_value, rate, c.unit) + ("" if c.printed else " †")


def _tolerance(c: Claim, rate: bool) -> str:
    """The tolerance our verdict allows: ours, not the paper's uncertainty (it prints none)."""
    if not c.tolerance:
        return "0"
    return ("± " if c.relation == "=" else "") + _num(c.tolerance, rate, c.unit)


def _reading(c: Claim, reading: str) -> str:
    return f"{reading} (shipped)" if c.shipped == reading else reading


def load_departures(path: Path = DEPARTURES) -> list[dict[str, str]]:
    """The departures table's rows (``departures.yaml``: paper, what, printed, ours, option, why)."""
    rows = yaml.safe_load(path.read_text()) if path.exists() else []
    keys = ("paper", "what", "printed", "ours", "option", "why")
    for row in rows:
        missing = [k for k in keys if k not in row]
        if missing:
            raise ValueError(f"{path.name}: departure {row.get('what', '?')!r} lacks {', '.join(missing)}")
    return rows


def departures_table(rows: list[dict[str, str]]) -> list[str]:
    """Markdown lines of the departures table."""
    lines = ["## Departures from the papers as printed", "",
             "Every place where a shipped default is not the paper's text as printed, with or without an",
             "option (\"none\": the departure cannot be switched off). Readings of a silent or ambiguous",
             "text are listed too.", "",
             "| paper | what | the paper prints | the default does | option | why |", "|---|---|---|---|---|---|"]
    for r in rows:
        cells = [str(r[k]).replace("|", "\\|").replace("\n", " ").strip() for k in
                 ("paper", "what", "printed", "ours", "option", "why")]
        lines.append("| " + " | ".join(cells) + " |")
    return lines + [""]


def markdown(outcomes: list[Outcome], meta: dict[str, Any]) -> str:
    """docs/reproduction.md from the outcomes."""
    lines = [
        "# Reproduction report",
        "",
        "Generated by `python benchmarks/reproduction/reproduce.py` from the claims in",
        "`benchmarks/reproduction/claims/`; do not",
        "edit by hand. Every number a paper prints that a shipped scenario reproduces, for each reading",
        "of the paper the number depends on. The first reading of a claim run on a shipped scenario is",
        "its shipped default; a function claim's first reading is the paper as printed, and where a",
        "shipped scenario flies another, that reading is marked \"(shipped)\" (VRB's Fig. 8: the first",
        "reading is the paper's literal triangle and gains, vrb_airshow ships calibrated ones). Where a",
        "default is not the paper as printed, the departures table at the end says so and why.",
        "\"paper\" is the number as the paper states it; a value marked † is not printed in the paper: it",
        "is our reading of its text or of a figure (the claim's note says which). \"tolerance\" is ours,",
        "not the paper's (it prints no uncertainty): how far from the paper's number \"holds\" allows",
        "(± for a value; for a bound, how far past it the worst seed may go).",
        "\"ours\" is the mean over seeds with its 95 % interval: Student t; the percentile bootstrap of the",
        "mean (10,000 resamples, fixed seed), whose ends stay within the values, for a quantity that",
        "cannot be negative (a distance, a speed, a time) and, from 10 seeds, wherever Student t would",
        "reach past every value observed (a signed quantity with a heavy tail); Wilson for rates. "
        "\"det.\" means every seed",
        "gave the same value. Where the paper's number is one run (a figure of one flight), it is judged",
        "on the share of our seeds that meet it (within tolerance; for a bound, at or past it), shown with",
        "its Wilson interval, never on our mean: such a value \"holds\" when at least half the seeds are",
        "within tolerance, and is \"in interval\" when it lies within the range of our seeds.",
        "\"run at\" is the commit the row's runs were made at. \"worst\" is the seed farthest from the",
        "paper (the maximum for an upper bound, the minimum for a lower bound; none for a rate). \"holds\"",
        "applies the tolerance; \"in interval\" says whether our interval (for bounds: every seed; for one",
        "flight: the range of seeds) meets the paper's value. The command reproduces the runs of one row.",
        "",
        f"Run: {meta['date']}, commit `{meta['commit']}`, {meta['runs']} runs ({meta['cached']} of them read "
        f"from `--cache`, run earlier by this command) in {meta['minutes']:.1f} min on {meta['jobs']} worker "
        "process(es). Numbers: `benchmarks/reproduction/results/reproduction.json`."
        + (f" {meta['note']}" if meta.get("note") else "")
        + (f" Re-run at this commit: {', '.join(f'`{i}`' for i in meta['rerun'])}; every other row is kept from the "
           "earlier report (its \"run at\" column), re-evaluated but not re-run." if meta.get("rerun") else ""),
        "",
    ]
    for paper, title in PAPERS.items():
        rows = [o for o in outcomes if o.claim.paper == paper]
        if not rows:
            continue
        lines += [f"## {title}", "",
                  "| claim | where | paper | tolerance | reading | seeds | ours | worst | holds | in interval "
                  "| run at |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for o in rows:
            c = o.claim
            lines.append(
                f"| {c.quantity} (`{c.id}`) | {c.where} | {_paper(c, o.rate)} | {_tolerance(c, o.rate)} | "
                f"{_reading(c, o.reading)} | "
                f"{len(o.values)} | {_ours(o)} | {'–' if o.rate else _num(o.worst, o.rate, c.unit)} | "
                f"{_verdict(o)} | {'yes' if o.contains_paper else '**no**'} | {o.run or meta['commit']} |"
            )
        lines.append("")
        lines += ["Commands (one run per seed; the last word selects the seeds):", ""]
        for c in {o.claim.id: o.claim for o in rows}.values():
            for reading in c.readings:
                lines.append(f"- `{c.id}`, {reading}: `{c.command(reading)}`")
        lines.append("")
    lines += departures_table(meta.get("departures", []))
    lines += ["## Where our interval does not meet the paper's value", ""]
    gaps = [o for o in outcomes if o.values and not o.contains_paper]
    if not gaps:
        lines.append("None.")
    for o in gaps:
        c = o.claim
        why = c.note.strip() or "no reason recorded in the claim"
        lines.append(f"- **{c.quantity}** ({c.where}; `{c.id}`, {o.reading}): paper "
                     f"{_paper(c, o.rate)} (tolerance {_tolerance(c, o.rate)}), ours {_ours(o)}. {why}")
    lines.append("")
    return "\n".join(lines)


def git_commit() -> str:
    """The commit the report ran from (the run manifests' own record of it), marked when the
    checkout had uncommitted changes; "unknown" outside a git checkout."""
    from swarmscene.runs.outputs import source_revision

    rev = source_revision()
    if rev is None:
        return "unknown"
    return rev["revision"][:7] + (" with uncommitted changes" if rev["dirty"] and _dirty_beyond_report() else "")


def _dirty_beyond_report() -> bool:
    """Whether tracked files other than the report's own outputs (which a re-run rewrites) differ
    from the commit; True when git cannot tell."""
    import subprocess

    outputs = {"docs/reproduction.md", "benchmarks/reproduction/results/reproduction.json"}
    try:
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                                capture_output=True, text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return True
    return any(line[3:].strip() not in outputs for line in status.splitlines() if line.strip())


def select(claims: list[Claim], only: list[str]) -> list[Claim]:
    """The claims whose id contains, or whose paper is, one of the words ``only`` (every claim when empty)."""
    if not only:
        return claims
    return [c for c in claims if any(word in c.id or word == c.paper for word in only)]


def main(argv: list[str] | None = None) -> int:
    """Run the chosen claims' jobs, evaluate them and write the markdown report and its JSON; the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", nargs="*", default=[], help="claims whose id contains, or paper is, a word")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes")
    parser.add_argument("--cache", type=Path, default=None, help="directory keeping finished runs (resume)")
    parser.add_argument("--markdown", type=Path, default=ROOT / "docs" / "reproduction.md")
    parser.add_argument("--json", type=Path, default=HERE / "results" / "reproduction.json")
    parser.add_argument("--note", default="",
                        help="a line for the report on the runs (e.g. where cached runs came from)")
    parser.add_argument("--keep", type=Path, default=None,
                        help="an earlier report's JSON: the claims --only leaves out are taken from it, "
                             "re-evaluated (not re-run), and the report still lists every claim")
    parser.add_argument("--cache-runs-at", default=None,
                        help="the commit the --cache runs were made at, for rows whose runs all came from the cache "
                             "(default: this commit)")
    parser.add_argument("--kept-runs", default=None,
                        help="the commit the kept rows' runs were made at (default: the kept report's commit)")
    args = parser.parse_args(argv)
    every = load_claims()
    claims = select(every, args.only)
    jobs = [job for c in claims for reading in c.readings for job in c.jobs(reading)]
    started = time.perf_counter()
    keys = {j.key for j in jobs}
    from_cache = {k for k in keys if (args.cache / f"{k}.json").exists()} if args.cache else set()
    cached = len(from_cache)
    results = run_jobs(jobs, args.jobs, args.cache)
    commit = git_commit()
    fresh = {(c.id, reading): evaluate(c, reading, results) for c in claims for reading in c.readings}
    for (claim_id, reading), outcome in fresh.items():
        claim = next(c for c in claims if c.id == claim_id)
        all_cached = all(job.key in from_cache for job in claim.jobs(reading))
        outcome.run = (args.cache_runs_at or commit) if all_cached else commit
    kept = kept_outcomes(args.keep, every, args.kept_runs) if args.keep is not None else {}
    rerun = {c.id for c in claims}
    outcomes = [fresh.get((c.id, r)) or kept.get((c.id, r)) or evaluate_values(c, r, [])
                for c in (every if args.keep is not None else claims) for r in c.readings]
    meta = {"date": time.strftime("%Y-%m-%d"), "commit": commit, "runs": len(keys), "cached": cached, "note": args.note,
            "minutes": (time.perf_counter() - started) / 60, "jobs": args.jobs,
            "rerun": sorted(rerun) if args.keep is not None else None}
    departures = load_departures()
    meta["departures"] = departures
    args.markdown.write_text(markdown(outcomes, meta))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"meta": {k: v for k, v in meta.items() if k != "departures"},
                                     "departures": departures,
                                     "outcomes": [o.as_dict() for o in outcomes]}, indent=1))
    surprises = [f"{o.claim.id} ({'holds' if o.holds else 'misses'}, expected {o.claim.expect})"
                 for o in outcomes if o.reading == o.claim.default_reading and o.holds != (o.claim.expect == "holds")]
    print(f"wrote {args.markdown} and {args.json}; default readings not as expected: {surprises or 'none'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
