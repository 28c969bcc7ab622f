"""Whether a sweep reproduces the shipped reference scores (docs/suite.md, "Reproducing").

``python -m swarmscene.suite check multirun/suite_v1`` scores the sweep's runs and compares them
with ``reference_<version>.csv``, run by run (task, method, seed) for the methods the sweep ran:

* **bit for bit**: the raw and normalised scores are the same floats;
* **within rtol**: they differ by at most ``rtol`` relative (default 1e-12). A change of how a
  metric is computed that is exact in real numbers can move its last bits (a different eigenvalue
  routine, a sum in another order), and so may numpy's and LAPACK's kernels, chosen for the CPU at
  hand, on another machine;
* the pass and success verdicts must be equal, and every reference run of those methods present
  (``--partial``: only the runs the sweep holds are compared, for a sweep of some tasks or seeds).

Anything else is a difference: the check prints the worst ones and fails.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .results import reference_rows

RTOL = 1e-12
"""Default relative tolerance of a score that is not the same float (module docstring)."""
SCORES = ("raw", "normalised")
VERDICTS = ("passed", "success")
SHOWN = 5
"""Differences printed, worst first."""


@dataclass
class Comparison:
    """How a sweep's rows compare with the reference's (keyed by task, method, seed)."""

    compared: int = 0
    identical: int = 0
    close: list[tuple[float, str]] = field(default_factory=list)  # (relative difference, where)
    different: list[tuple[float, str]] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    @property
    def reproduced(self) -> bool:
        """Every reference run present, its scores within the tolerance, its verdicts equal."""
        return not self.different and not self.missing and self.compared > 0


def _key(row: dict[str, Any]) -> tuple[str, str, int]:
    return row["task"], row["method"], int(row["seed"])


def _relative(a: float, b: float) -> float:
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def compare(rows: list[dict[str, Any]], reference: list[dict[str, Any]], rtol: float = RTOL,
            partial: bool = False) -> Comparison:
    """Compare ``rows`` with the ``reference`` rows of the methods ``rows`` holds (``partial``: only
    the runs ``rows`` holds; a reference run it lacks is not missing)."""
    mine = {_key(r): r for r in rows}
    methods = {r["method"] for r in rows}
    out = Comparison()
    for ref in reference:
        if ref["method"] not in methods:
            continue
        where = "{} {} seed {}".format(*_key(ref))
        row = mine.get(_key(ref))
        if row is None:
            if not partial:
                out.missing.append(where)
            continue
        out.compared += 1
        verdicts = [k for k in VERDICTS if row[k] != ref[k]]
        worst, name = max((_relative(row[k], ref[k]), k) for k in SCORES)
        if verdicts:
            out.different.append((max(worst, 1.0), f"{where}: {', '.join(verdicts)} {row[verdicts[0]]} "
                                                    f"(reference {ref[verdicts[0]]})"))
        elif worst > rtol:
            out.different.append((worst, f"{where}: {name} {row[name]!r} (reference {ref[name]!r})"))
        elif worst > 0:
            out.close.append((worst, f"{where}: {name}"))
        else:
            out.identical += 1
    return out


def report(c: Comparison, version: str, rtol: float) -> str:
    """The check's lines: the verdict first, then the worst differences."""
    if c.compared == 0 and not c.missing:
        return f"swarmscene-bench {version}: no run of a reference method to compare"
    head = (f"swarmscene-bench {version}: {c.compared} runs compared with the reference: {c.identical} bit for "
            f"bit, {len(c.close)} within rtol {rtol:g}")
    if c.close:
        rel, where = max(c.close)
        head += f" (largest {rel:.2g}: {where})"
    head += f", {len(c.different)} different, {len(c.missing)} missing"
    head += "; reproduced" if c.reproduced else "; NOT reproduced"
    lines = [head]
    lines += [f"  different: {where}" for _, where in sorted(c.different, reverse=True)[:SHOWN]]
    lines += [f"  missing: {where}" for where in c.missing[:SHOWN]]
    return "\n".join(lines)


def check_sweep(sweep_dir: Path | str, version: str = "v1", rtol: float = RTOL,
                partial: bool = False) -> tuple[bool, str]:
    """Whether ``sweep_dir``'s scores reproduce the reference, and the report."""
    if not rtol >= 0:
        raise ValueError(f"--rtol: must be >= 0 (got {rtol})")
    from .score import score_sweep

    # scored again from the run directories: suite/scores.csv also lists the reference's rows of
    # the methods a sweep did not run, which would compare equal to themselves
    scored, _ = score_sweep(Path(sweep_dir))
    rows = [s.row() for s in scored if s.version == version]
    reference = reference_rows(version)
    if not reference:
        raise ValueError(f"no reference scores are shipped for {version}")
    result = compare(rows, reference, rtol, partial)
    return result.reproduced, report(result, version, rtol)
