"""Whether a result is current: the closure of its roots hashes today as it did, and its
packaged config has the content it had (:mod:`~ilc_steering.engine.provenance` records both).

:func:`staleness` judges one result (a cell, a row, an oracle, a script's artifact);
:func:`freshness` a run folder's results, grouped by learner and reason, for
``ilc-steering current`` (:mod:`ilc_steering.current`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ilc_steering import __version__
from ilc_steering.engine.provenance import CodeRecord, changed, code, provenance, read_run

__all__ = ["Staleness", "configs_today", "freshness", "staleness"]


@dataclass(frozen=True)
class Staleness:
    """Why one result is stale: the files of its closure that changed, or its config's content."""

    files: tuple[str, ...] = ()
    config: str | None = None
    """The config whose packaged content is not the one the result was computed with."""
    unknown: str | None = None
    """A result that records no code, or a code its run.json does not hold."""

    def __bool__(self) -> bool:
        return bool(self.files or self.config or self.unknown)

    def text(self) -> str:
        parts = []
        if self.unknown:
            parts.append(self.unknown)
        if self.files:
            shown = ", ".join(self.files[:6]) + (f" and {len(self.files) - 6} more" if len(self.files) > 6 else "")
            parts.append(f"{len(self.files)} file{'s' * (len(self.files) > 1)} changed: {shown}")
        if self.config:
            parts.append(f"config {self.config} changed")
        return "; ".join(parts)


def staleness(result: Mapping[str, Any], codes: Mapping[str, CodeRecord], configs: Mapping[str, str]) -> Staleness:
    """Why ``result`` (a cell, a row, an oracle) is stale for the code in this tree, or an empty
    :class:`Staleness` when it is current. ``codes``: its run's table; ``configs``: config name ->
    the content hash today (packaged configs only: a user's file is not checked)."""
    recorded = result.get("code")
    if not isinstance(recorded, str):
        return Staleness(unknown="records no code (made before results kept their own)")
    made = codes.get(recorded)
    if made is None:
        return Staleness(unknown=f"its code {recorded} is not in run.json's codes")
    now, files = code(made.roots)
    moved = tuple(changed(made.files, files)) if now != recorded else ()
    name, sha = result.get("config"), result.get("config_sha")
    config = name if isinstance(name, str) and name in configs and configs[name] != sha else None
    return Staleness(files=moved, config=config)


def configs_today(names: Iterable[str]) -> dict[str, str]:
    """The content hash today of each packaged config among ``names``."""
    from dataclasses import asdict

    from ilc_steering.config import load_config, packaged_configs
    from ilc_steering.output import content_hash

    packaged = packaged_configs()
    return {name: content_hash(asdict(load_config(name))) for name in set(names) if name in packaged}


def freshness(folder: Path, results: Mapping[str, dict[str, Any]], label: str) -> tuple[int, list[str], float]:
    """How many results of the run in ``folder`` are stale for the code in this tree, the lines
    that say why, grouped by the value of ``label`` (``method``) and reason, and the seconds of one
    core the stale ones took (their wall times). ``results``: where each result was read -> the
    result, with its config's name under ``"config"``."""
    _, run = read_run(folder)
    today = configs_today(r["config"] for r in results.values() if isinstance(r.get("config"), str))
    groups: Counter[tuple[str, str]] = Counter()
    cost = 0.0
    for result in results.values():
        why = staleness(result, run.codes, today)
        if why:
            groups[str(result.get(label, "?")), why.text()] += 1
            wall = result.get("wall_s")
            cost += float(wall) if isinstance(wall, (int, float)) else 0.0
    stale = sum(groups.values())
    lines = [f"  {count} of {name}: {why}" for (name, why), count in sorted(groups.items())]
    if stale:
        lines.append(f"  a resume recomputes them: about {cost / 60:.1f} minutes of one core (their wall times)")
    made = run.provenance
    if made is not None and made.version != __version__:
        lines.append(f"  version: made by ilc-steering {made.version}, the tree is {__version__}")
        stale = len(results)
        cost = sum(float(r["wall_s"]) for r in results.values() if isinstance(r.get("wall_s"), (int, float)))
    last = run.sessions[-1].packages if run.sessions else None
    before = last or (made.packages if made else {})
    after = provenance()["packages"]
    moved = [  # a package the record did not know (newly tracked) is no change
        f"{p} {before[p]} -> {after.get(p)}"
        for p in sorted(before)
        if before[p] is not None and before[p] != after.get(p)
    ]
    if moved:
        lines.append("  packages (results may differ; not stale for it): " + ", ".join(moved))
    return stale, lines, cost
