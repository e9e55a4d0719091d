"""The statistics of ``compare``: per (prior, method, scenario) and tolerance of :data:`LADDER`,
the median and interquartile mean of the trials to it over seeds, each with a 95 % percentile
bootstrap interval (:func:`scipy.stats.bootstrap`, seeded), a seed that never got there censored;
and the ratios of ILC to the best method of each family."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    pass

__all__ = ["LADDER", "LADDER_NAMES", "bootstrap_median", "quartiles", "ratios", "statistic_ci", "summarize"]

LADDER = {"10cm": 0.1, "1cm": 0.01, "1mm": 1e-3, "0.5mm": 5e-4}
"""Tolerances: the Cartesian error [m] and the orientation error [rad] both within the value (a
chained plant: its error norm ``||z^d - z(T)||``)."""
LADDER_NAMES = {
    "10cm": "10 cm / 0.1 rad",
    "1cm": "1 cm / 0.01 rad",
    "1mm": "1 mm / 1 mrad",
    "0.5mm": "0.5 mm / 0.5 mrad",
}

BOOTSTRAP_RESAMPLES = 2000
CENSORED = 1e15
"""Where a seed that never reached a level stands in a bootstrap (``inf`` has no arithmetic): any
statistic it enters exceeds :data:`UNREACHED`, and is reported as not within the budget."""
UNREACHED = 1e9


def quartiles(values: list[float]) -> tuple[float, float, float]:
    """Quartiles as order statistics (no interpolation): ``inf`` (not reached) stays ``inf``."""
    q1, q2, q3 = np.percentile(np.asarray(values, dtype=np.float64), [25, 50, 75], method="inverted_cdf")
    return float(q1), float(q2), float(q3)


def _median(data: Any, axis: int = -1) -> Any:
    return np.median(data, axis=axis)


def _iqm(data: Any, axis: int = -1) -> Any:
    """The interquartile mean: the mean of the middle half (``scipy.stats.trim_mean``, a quarter cut
    from each end), the aggregate Agarwal et al. (NeurIPS 2021) recommend over few seeds."""
    from scipy.stats import trim_mean

    return trim_mean(data, 0.25, axis=axis)


STATISTICS = {"median": _median, "iqm": _iqm}
"""The statistics of trials to a level across seeds, each with a bootstrap interval."""


def _uncensored(value: float) -> float:
    return math.inf if value > UNREACHED else float(value)


def statistic_ci(values: list[float], statistic: str, seed: int = 0) -> tuple[float, tuple[float, float] | None]:
    """``statistic`` (``median`` or ``iqm``) of ``values`` (trials; ``inf``: not reached) and its
    95 % percentile-bootstrap confidence interval from ``scipy.stats.bootstrap``
    (:data:`BOOTSTRAP_RESAMPLES` resamples of the seeds, seeded); None for fewer than two seeds. A
    statistic or bound that a seed which never got there enters is ``inf`` (:data:`CENSORED`)."""
    from scipy.stats import bootstrap

    function = STATISTICS[statistic]
    data = np.where(np.isinf(values), CENSORED, np.asarray(values, dtype=np.float64))
    value = _uncensored(float(function(data)))
    if data.size < 2:
        return value, None
    if np.all(data == data[0]):  # every resample is the sample: the interval is the point
        return value, (value, value)
    result = bootstrap(
        (data,),
        function,
        n_resamples=BOOTSTRAP_RESAMPLES,
        confidence_level=0.95,
        method="percentile",
        vectorized=True,
        rng=np.random.default_rng(seed),
    )
    low, high = result.confidence_interval
    return value, (_uncensored(float(low)), _uncensored(float(high)))


def bootstrap_median(values: list[float], seed: int = 0) -> tuple[float, float]:
    """The 95 % bootstrap confidence interval of the median (:func:`statistic_ci`); ``(v, v)`` for
    one seed."""
    value, interval = statistic_ci(values, "median", seed)
    return interval if interval is not None else (value, value)


def summarize(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One summary row per (prior, method, scenario), in the cells' order."""
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for cell in cells:
        groups.setdefault((cell["prior"], cell["scenario"], cell["method"]), []).append(cell)
    rows = []
    for (prior, scenario, method), group in groups.items():
        row: dict[str, Any] = {
            "prior": prior,
            "scenario": scenario,
            "method": method,
            "budget": group[0]["budget"],
            "seeds": len(group),
        }
        for level in LADDER:
            reached = [math.inf if c["trials_to"][level] is None else c["trials_to"][level] for c in group]
            entry: dict[str, Any] = {"q1_median_q3": quartiles(reached)}
            for name in STATISTICS:
                value, interval = statistic_ci(reached, name)
                entry[name] = value
                entry[f"{name}_ci95"] = interval
            entry["reached"] = int(np.isfinite(reached).sum())
            entry["fragile"] = sum(level in c.get("fragile", ()) for c in group)
            row[f"trials_to_{level}"] = entry
        row["best_error_q1_median_q3"] = quartiles([c["best_error"] for c in group])
        row["off_chart_fraction_median"] = float(np.median([c["off_chart_fraction"] for c in group]))
        row["clipped_fraction_median"] = float(np.median([c.get("clipped_fraction", 0.0) for c in group]))
        row["wall_s_median"] = float(np.median([c["wall_s"] for c in group]))
        updates = [c["update_s"] for c in group if c.get("update_s") is not None]
        row["update_s_median"] = float(np.median(updates)) if updates else None
        rows.append(row)
    return rows


def _median_trials(row: dict[str, Any], level: str) -> float:
    return float(row[f"trials_to_{level}"]["median"])


def ratios(rows: list[dict[str, Any]], families: dict[str, tuple[str, ...]]) -> list[dict[str, Any]]:
    """Per (prior, scenario, tolerance): ILC's median trials and, per family of methods, the best
    one's median (the fewest; ``inf`` when none got there in half the seeds) with its ratio to ILC."""
    out = []
    for prior, scenario in dict.fromkeys((r["prior"], r["scenario"]) for r in rows):
        group = {r["method"]: r for r in rows if r["prior"] == prior and r["scenario"] == scenario}
        if "ilc" not in group:
            continue
        for level in LADDER:
            ilc = _median_trials(group["ilc"], level)
            entry: dict[str, Any] = {"prior": prior, "scenario": scenario, "tolerance": level, "ilc": ilc}
            for family, methods in families.items():
                medians = {m: _median_trials(group[m], level) for m in methods if m in group}
                if medians:
                    best = min(medians, key=lambda m: medians[m])
                    entry[family] = {"method": best, "median": medians[best], "ratio": medians[best] / ilc}
            out.append(entry)
    return out
