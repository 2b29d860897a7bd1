"""The reproduction report: one self-contained HTML page for `attend reproduce all`.

Each experiment's figures (embedded as PNG), one table of reproduced vs published values, the
settings, the software versions and the exact commands. Results are cached by configuration:
a key made of the experiment name, quick/full mode and a hash of attend's source code; a rerun
reuses OUT/NAME.json (and its figures) when its key matches.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import platform
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from attend.experiments._result import ExperimentResult

_PACKAGE_ROOT = Path(__file__).resolve().parent


def source_hash() -> str:
    """SHA-256 over attend's Python sources: any code change invalidates the cache."""
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE_ROOT.rglob("*.py")):
        digest.update(path.relative_to(_PACKAGE_ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_key(name: str, quick: bool, code_hash: str | None = None) -> str:
    text = json.dumps({"experiment": name, "quick": quick, "code": code_hash or source_hash()}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cached_result(out_dir: Path, name: str, key: str) -> ExperimentResult | None:
    """The stored result of ``name`` if its cache key matches and its figures exist."""
    path = Path(out_dir) / f"{name}.json"
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    if data.get("cache_key") != key:
        return None
    result = ExperimentResult.from_json_dict(data)
    result.figures = result.relative_figures(out_dir)
    if not all((Path(out_dir) / figure).is_file() for figure in result.figures):
        return None
    return result


def software_versions() -> dict[str, str]:
    versions = {"python": sys.version.split()[0], "platform": platform.platform()}
    for package in ("attend", "numpy", "scipy", "matplotlib", "pykalman", "cma"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = "not installed"
    return versions


def _format(value) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.6g}"
    return html.escape(str(value))


def write_report(out_dir, results: list[ExperimentResult], descriptions: dict[str, str], command: str,
                 total_seconds: float) -> Path:
    """Write OUT/index.html and return its path."""
    out = Path(out_dir)
    rows = []
    for result in results:
        for metric in result.metrics:
            difference = metric.relative_difference()
            status = ""
            if difference is not None:
                status = f"{difference * 100:.2f} %"
            rows.append(
                f"<tr><td>{html.escape(result.experiment)}</td><td>{html.escape(metric.name)}</td>"
                f"<td>{_format(metric.value)}</td><td>{_format(metric.published)}</td>"
                f"<td>{status}</td><td>{html.escape(metric.unit)}</td></tr>"
            )
    sections = []
    for result in results:
        figures = []
        for figure in result.relative_figures(out):
            path = out / figure
            if path.suffix.lower() in (".png", ".gif") and path.is_file():
                encoded = base64.b64encode(path.read_bytes()).decode()
                mime = "image/gif" if path.suffix.lower() == ".gif" else "image/png"
                figures.append(f'<figure><img src="data:{mime};base64,{encoded}" alt="{html.escape(figure)}">'
                               f"<figcaption>{html.escape(figure)}</figcaption></figure>")
        notes = "".join(f"<li>{html.escape(note)}</li>" for note in result.notes)
        runtime = f"{result.runtime_s:.1f} s" if result.runtime_s is not None else "cached"
        sections.append(
            f'<section id="{html.escape(result.experiment)}"><h2>{html.escape(result.experiment)}</h2>'
            f"<p>{html.escape(descriptions.get(result.experiment, ''))}</p>"
            f"<p>Command: <code>attend reproduce {html.escape(result.experiment)}"
            f"{'' if result.settings.get('quick', True) else ' --full'}</code>; run time {runtime}.</p>"
            f"{''.join(figures)}{'<ul>' + notes + '</ul>' if notes else ''}"
            f"<details><summary>settings</summary><pre>{html.escape(json.dumps(result.to_json_dict()['settings'], indent=1))}</pre></details>"
            "</section>"
        )
    versions = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in software_versions().items())
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>attend: reproduction report</title>
<style>
body {{ font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em; color: #222; }}
table {{ border-collapse: collapse; margin: 1em 0; }} td, th {{ border: 1px solid #ccc; padding: 3px 8px; text-align: left; }}
th {{ background: #f0f0f0; }} img {{ max-width: 100%; }} figure {{ margin: 1em 0; }}
code {{ background: #f4f4f4; padding: 1px 4px; }} section {{ border-top: 2px solid #ddd; margin-top: 2em; }}
</style></head><body>
<h1>attend: reproduction of "Reclaiming saliency: rhythmic precision-modulated action and perception"</h1>
<p>Generated {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} by <code>{html.escape(command)}</code>
in {total_seconds:.1f} s. Each experiment's JSON sits beside this page.</p>
<h2>Reproduced vs published</h2>
<table><tr><th>experiment</th><th>metric</th><th>reproduced</th><th>published</th><th>|difference|</th><th>unit</th></tr>
{''.join(rows)}</table>
{''.join(sections)}
<h2>Software</h2><table>{versions}</table>
</body></html>
"""
    path = out / "index.html"
    path.write_text(page)
    return path
