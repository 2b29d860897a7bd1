"""The common result contract of every reproduction experiment.

`attend reproduce NAME --out DIR` writes ``DIR/NAME.json`` holding::

    {"experiment": NAME,
     "metrics": [{"name": ..., "value": ..., "published": ... or null, "unit": ...}],
     "settings": {...}}

so that reproduced and published values stand side by side, plus PNG figures in DIR. The
figure paths in the JSON are relative to DIR (so the folder can be moved, and a relative
``--out`` does not count twice).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Metric:
    """One reproduced figure, with the published value it is compared to (or None)."""

    name: str
    value: float
    unit: str
    published: float | None = None

    def relative_difference(self) -> float | None:
        """|value - published| / |published|, or None when nothing was published."""
        if self.published is None or self.published == 0:
            return None
        return abs(self.value - self.published) / abs(self.published)


#: The verdicts a claim can get in the report.
VERDICTS = ("reproduced", "differs", "does not hold")


@dataclass(frozen=True)
class Claim:
    """One claim of the paper as attend tested it: the claim in words, what attend measured (with
    units), the published value where there is one, and the verdict, one of :data:`VERDICTS`."""

    claim: str
    measured: str
    verdict: str
    published: str | None = None

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"claim verdict {self.verdict!r}; expected one of {', '.join(VERDICTS)}")

    def to_json_dict(self) -> dict[str, Any]:
        return {"claim": self.claim, "measured": self.measured, "published": self.published,
                "verdict": self.verdict}


@dataclass
class ExperimentResult:
    """Metrics, settings and figure files of one experiment run."""

    experiment: str
    metrics: list[Metric] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)
    figures: list[str] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    runtime_s: float | None = None
    cache_key: str | None = None
    tables: dict[str, Any] = field(default_factory=dict)

    def add(self, name: str, value: float, unit: str, published: float | None = None) -> None:
        self.metrics.append(Metric(name, float(value), unit, published))

    def metric(self, name: str) -> Metric:
        for metric in self.metrics:
            if metric.name == name:
                return metric
        raise KeyError(f"experiment {self.experiment!r} has no metric {name!r}")

    def to_json_dict(self) -> dict[str, Any]:
        """The JSON form; ``tables`` (structured results beyond the metrics, e.g. a per-setting
        map) appear under their own keys when there are any."""
        data = {
            "experiment": self.experiment,
            "metrics": [
                {
                    "name": m.name,
                    "value": _finite_or_none(m.value),
                    "published": m.published,
                    "unit": m.unit,
                }
                for m in self.metrics
            ],
            "settings": _jsonable(self.settings),
            "figures": list(self.figures),
            "notes": list(self.notes),
            "runtime_s": self.runtime_s,
            "cache_key": self.cache_key,
        }
        return data | {key: _jsonable(value) for key, value in self.tables.items() if key not in data}

    @classmethod
    def from_json_dict(cls, data: dict[str, Any]) -> "ExperimentResult":
        """Rebuild a result (without its raw data) from its JSON form."""
        metrics = [
            Metric(m["name"], float("nan") if m["value"] is None else m["value"], m["unit"], m["published"])
            for m in data["metrics"]
        ]
        known = {"experiment", "metrics", "settings", "figures", "notes", "runtime_s", "cache_key"}
        return cls(data["experiment"], metrics, data.get("settings", {}), data.get("figures", []),
                   notes=data.get("notes", []), runtime_s=data.get("runtime_s"), cache_key=data.get("cache_key"),
                   tables={key: value for key, value in data.items() if key not in known})

    def relative_figures(self, out_dir: str | Path) -> list[str]:
        """The figure paths relative to ``out_dir`` (those outside it stay as they are)."""
        return [figure_name(figure, out_dir) for figure in self.figures]

    def write(self, out_dir: str | Path) -> Path:
        """Write ``out_dir/<experiment>.json`` (figure paths relative to ``out_dir``) and return its path."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        self.figures = self.relative_figures(out)
        path = out / f"{self.experiment}.json"
        path.write_text(json.dumps(self.to_json_dict(), indent=2) + "\n")
        return path

    def table(self) -> str:
        """A plain-text table: name, reproduced, published, unit."""
        rows = [("metric", "reproduced", "published", "unit")]
        for m in self.metrics:
            published = "-" if m.published is None else f"{m.published:.6g}"
            rows.append((m.name, f"{m.value:.6g}", published, m.unit))
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)


def figure_name(path: str | Path, out_dir: str | Path) -> str:
    """``path`` relative to ``out_dir`` when it lies inside it ("results/fig3.png" -> "fig3.png"
    for out_dir "results"), else unchanged; a bare name stays a name."""
    path, out = Path(path), Path(out_dir)
    if not path.is_absolute() and not path.parts[: len(out.parts)] == out.parts:
        return path.as_posix()  # already relative to out_dir
    try:
        return path.resolve().relative_to(out.resolve()).as_posix()
    except ValueError:
        return str(path)


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
