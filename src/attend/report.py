"""The reproduction report: one self-contained HTML page for `attend reproduce all` and `attend report`.

It opens with the claims table (each experiment module's ``claims(result)``: claim, measured,
published, verdict), then each experiment's figures (embedded as PNG) with their captions from
the module's ``CAPTIONS``, the settings, the full metric table (folded away) and the software
versions. :func:`rebuild` redraws every figure from the JSON files alone. Results are cached by configuration:
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

from attend._validation import AttendInputError
from attend.experiments._result import Claim, ExperimentResult

_PACKAGE_ROOT = Path(__file__).resolve().parent


def source_hash() -> str:
    """SHA-256 over attend's Python sources: any code change invalidates the cache."""
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE_ROOT.rglob("*.py")):
        digest.update(path.relative_to(_PACKAGE_ROOT).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_key(name: str, quick: bool, code_hash: str | None = None) -> str:
    """The cache key of experiment ``name`` in quick or full mode (``quick``) for the source code of
    hash ``code_hash`` (default: :func:`source_hash` of this installation): 16 hex digits."""
    text = json.dumps({"experiment": name, "quick": quick, "code": code_hash or source_hash()}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cached_result(out_dir: Path, name: str, key: str) -> ExperimentResult | None:
    """The stored result of ``name`` in ``out_dir`` if its cache ``key`` matches and its figures exist."""
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


def load_result(path: str | Path) -> ExperimentResult:
    """The result stored in ``path`` (an ``attend reproduce`` NAME.json). Raises AttendInputError
    naming the file when it is missing, unreadable or not a result."""
    path = Path(path)
    if not path.is_file():
        raise AttendInputError(f"{path}: no such result file; expected the JSON that 'attend reproduce "
                               f"{path.stem} --out {path.parent}' writes")
    try:
        data = json.loads(path.read_text())
        result = ExperimentResult.from_json_dict(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise AttendInputError(f"{path}: not valid JSON ({error}); rerun 'attend reproduce {path.stem} "
                               f"--out {path.parent} --force'") from None
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise AttendInputError(f"{path}: not an attend result (missing or malformed {error}); rerun 'attend "
                               f"reproduce {path.stem} --out {path.parent} --force'") from None
    return result


def _module(name: str):
    """The experiment module of ``name``, or None when it is unknown or not installed."""
    from attend import experiments

    try:
        return experiments.load(name)
    except (KeyError, ImportError):
        return None


def rebuild(out_dir: str | Path, names: list[str] | None = None) -> list[ExperimentResult]:
    """Rebuild every figure of the results in ``out_dir`` from their JSON alone.

    names: the experiments (default: every known experiment with an ``out_dir/NAME.json``). For
    each, the module's ``plot(result, out_dir)`` redraws the figures (a JSON without tables, written
    before the figures' data were kept, keeps the figures it lists).
    Raises AttendInputError naming the file when a JSON is missing or corrupt, or when the folder
    holds no result at all. Returns the results, figures relative to ``out_dir``."""
    from attend import experiments

    out = Path(out_dir)
    if names is None:
        names = [name for name in experiments.EXPERIMENTS if (out / f"{name}.json").is_file()]
        if not names:
            raise AttendInputError(f"{out}: holds no result (NAME.json); expected the --out folder of "
                                   "'attend reproduce'")
    results = []
    for name in names:
        result = load_result(out / f"{name}.json")
        module = _module(result.experiment)
        if module is not None and hasattr(module, "plot") and result.tables:
            try:
                result.figures = list(module.plot(result, out))
            except (KeyError, IndexError, TypeError, ValueError) as error:
                raise AttendInputError(f"{out / f'{name}.json'}: its tables do not hold what the {name} figures "
                                       f"need ({type(error).__name__}: {error}); rerun 'attend reproduce {name} "
                                       f"--out {out} --force'") from None
        result.figures = result.relative_figures(out)
        results.append(result)
    return results


def experiment_claims(result: ExperimentResult) -> list[Claim]:
    """The claims of ``result``'s module (``claims(result)``); none when the module has no claims or
    the result predates them (an old JSON without the metrics or tables they need)."""
    module = _module(result.experiment)
    if module is None or not hasattr(module, "claims"):
        return []
    try:
        return list(module.claims(result))
    except (KeyError, IndexError, TypeError, ValueError):
        return []


def _captions(result: ExperimentResult) -> dict[str, str]:
    module = _module(result.experiment)
    captions = getattr(module, "CAPTIONS", None) if module is not None else None
    return dict(captions) if isinstance(captions, dict) else {}


_VERDICT_COLOURS = {"reproduced": "#d4edda", "differs": "#fff3cd", "does not hold": "#f8d7da"}


def _claims_table(results: list[ExperimentResult]) -> str:
    rows = []
    for result in results:
        for claim in experiment_claims(result):
            colour = _VERDICT_COLOURS.get(claim.verdict, "#ffffff")
            rows.append(f'<tr><td><a href="#{html.escape(result.experiment)}">{html.escape(result.experiment)}</a></td>'
                        f"<td>{html.escape(claim.claim)}</td><td>{html.escape(claim.measured)}</td>"
                        f"<td>{_format(claim.published)}</td>"
                        f'<td class="verdict" style="background: {colour}">{html.escape(claim.verdict)}</td></tr>')
    if not rows:
        return '<table id="claims"><tr><td>No experiment in this folder states claims.</td></tr></table>'
    return ('<table id="claims"><tr><th>experiment</th><th>claim</th><th>measured</th><th>published</th>'
            f"<th>verdict</th></tr>{''.join(rows)}</table>")


def _metrics_table(results: list[ExperimentResult]) -> str:
    rows = []
    for result in results:
        for metric in result.metrics:
            difference = metric.relative_difference()
            status = "" if difference is None else f"{difference * 100:.2f} %"
            rows.append(
                f"<tr><td>{html.escape(result.experiment)}</td><td>{html.escape(metric.name)}</td>"
                f"<td>{_format(metric.value)}</td><td>{_format(metric.published)}</td>"
                f"<td>{status}</td><td>{html.escape(metric.unit)}</td></tr>"
            )
    return ('<details id="metrics"><summary>All metrics: reproduced vs published</summary><table><tr>'
            "<th>experiment</th><th>metric</th><th>reproduced</th><th>published</th><th>|difference|</th>"
            f"<th>unit</th></tr>{''.join(rows)}</table></details>")


def _section(result: ExperimentResult, out: Path, descriptions: dict[str, str]) -> str:
    captions = _captions(result)
    figures = []
    for figure in result.relative_figures(out):
        path = out / figure
        if path.suffix.lower() in (".png", ".gif") and path.is_file():
            encoded = base64.b64encode(path.read_bytes()).decode()
            mime = "image/gif" if path.suffix.lower() == ".gif" else "image/png"
            caption = captions.get(figure, captions.get(path.name, figure))
            figures.append(f'<figure><img src="data:{mime};base64,{encoded}" alt="{html.escape(figure)}">'
                           f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    notes = "".join(f"<li>{html.escape(note)}</li>" for note in result.notes)
    runtime = f"{result.runtime_s:.1f} s" if result.runtime_s is not None else "cached"
    settings = html.escape(json.dumps(result.to_json_dict()["settings"], indent=1))
    return (
        f'<section id="{html.escape(result.experiment)}"><h2>{html.escape(result.experiment)}</h2>'
        f"<p>{html.escape(descriptions.get(result.experiment, ''))}</p>"
        f"<p>Command: <code>attend reproduce {html.escape(result.experiment)}"
        f"{'' if result.settings.get('quick', True) else ' --full'}</code>; run time {runtime}.</p>"
        f"{''.join(figures)}{'<ul>' + notes + '</ul>' if notes else ''}"
        f"<details><summary>settings</summary><pre>{settings}</pre></details></section>"
    )


_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 1200px; margin: 2em auto; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 1em 0; } td, th { border: 1px solid #ccc; padding: 3px 8px; text-align: left; }
th { background: #f0f0f0; } img { max-width: 100%; } figure { margin: 1em 0; }
figcaption { max-width: 60em; color: #444; } code { background: #f4f4f4; padding: 1px 4px; }
section { border-top: 2px solid #ddd; margin-top: 2em; }
"""


def write_report(out_dir, results: list[ExperimentResult], descriptions: dict[str, str], command: str,
                 total_seconds: float) -> Path:
    """Write OUT/index.html and return its path: the claims table (claim, measured, published,
    verdict) first, then each experiment's figures with their captions, the full metric table
    folded in a <details> element, and the software versions. out_dir: the results folder;
    results: the experiments' results; descriptions: name -> one line; command: the command that
    made the page; total_seconds: its run time [s]."""
    out = Path(out_dir)
    sections = "".join(_section(result, out, descriptions) for result in results)
    versions = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in software_versions().items())
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>attend: reproduction report</title>
<style>{_STYLE}</style></head><body>
<h1>attend: reproduction of "Reclaiming saliency: rhythmic precision-modulated action and perception"</h1>
<p>Generated {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} by <code>{html.escape(command)}</code>
in {total_seconds:.1f} s. Each experiment's JSON sits beside this page; <code>attend report DIR</code> rebuilds
the figures and this page from them.</p>
<h2>Claims of the paper: measured vs published</h2>
{_claims_table(results)}
{sections}
<h2>Metrics</h2>
{_metrics_table(results)}
<h2>Software</h2><table>{versions}</table>
</body></html>
"""
    path = out / "index.html"
    path.write_text(page)
    return path
