"""The first page of the HTML report: what each scene found, before how it was computed (issue #22).

Snakemake's report opens on the workflow description (``workflow/report/workflow.rst``), which
inserts the page this module writes. For a patient scene it gives the fit verdict, the estimate
with its 95 % intervals and the measurements against the model's, in clinical units (mm, cm², ml),
and the shape pictures; for a synthetic study its error table and convergence figure; for the
other scenes their main figure. Pictures are inlined, so the report stays one file.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

import pandas as pd

from breastcore.report.clinical import estimate_rows, fit_rows
from breastcore.report.html_tables import TABLE_CSS, table_html
from breastcore.report.summaries import error_table_with_units

#: Snakemake's workflow panel centres its content vertically in a screen-high box, which cuts off
#: the top of a description longer than the screen, and keeps the description narrow (max-w-lg)
#: beside the rule graph. The page starts at the top, takes the width, and the graph follows it.
REPORT_LAYOUT_CSS = """
div.h-screen.items-center { align-items: flex-start !important; justify-content: flex-start !important; }
div.grow.flex.gap-3.items-start { flex-wrap: wrap; }
div.prose.max-w-lg { max-width: min(64rem, 100%) !important; }
div.breastcore-table { overflow-x: auto; max-width: 100%; }
div.breastcore-table table.breastcore { width: auto; }
img.breastcore { display: inline-block; margin: 0 0.5em 0.5em 0; }
"""
#: Scene kinds in the order the page shows them: a patient's findings first.
KIND_ORDER = ("patient", "forward", "synthetic", "calibration", "stability")
KIND_TITLES = {"patient": "Patient", "synthetic": "Synthetic identification study", "forward": "Forward solve",
               "stability": "Stability study", "calibration": "Calibration of the Chassaignac coefficient"}


def picture(path, alt, width="32%") -> str:
    """``<img>`` of a PNG file, inlined as a data URI."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return (f'<img class="breastcore" src="data:image/png;base64,{data}" alt="{html.escape(alt)}" '
            f'style="width:{width};min-width:280px;vertical-align:top">')


def estimate_table(ds) -> pd.DataFrame:
    """The estimate with its 95 % interval per parameter, clinical units."""
    rows = []
    for name, value, unit, interval in estimate_rows(ds):
        low, high = (interval if not isinstance(interval, str) else (float("nan"), float("nan")))
        note = interval if isinstance(interval, str) else "determined"
        rows.append({"parameter": name, "estimate": value, "unit": unit, "95 % low": low, "95 % high": high,
                     "note": note})
    return pd.DataFrame(rows)


def fit_table(ds) -> pd.DataFrame:
    """Measured against fitted per posture and quantity, clinical units."""
    return pd.DataFrame([{"posture": posture, "quantity": quantity, "unit": unit, "measured": m, "fitted": f,
                          "difference %": 100.0 * (f / m - 1.0), "among the worst": "yes" if worst else ""}
                         for posture, quantity, unit, m, f, worst in fit_rows(ds)])


def _patient(ds, pictures):
    parts = []
    if "verdict" in ds.attrs:
        parts.append(f"<p class=\"verdict\"><b>Fit verdict: {html.escape(ds.attrs['verdict'])}</b>: "
                     f"{html.escape(ds.attrs.get('verdict_message', ''))}</p>")
    if "estimate" in ds and "determined" in ds:
        parts += ["<h3>Estimate and 95 % intervals</h3>", table_html(estimate_table(ds))]
    fit = fit_table(ds)
    if not fit.empty:
        parts += ["<h3>Measured against fitted</h3>", table_html(fit)]
    return parts + _pictures("Shapes", pictures)


def _pictures(heading, pictures, width="32%"):
    if not pictures:
        return []
    return [f"<h3>{heading}</h3>", "<p>" + " ".join(picture(p, Path(p).stem, width) for p in pictures) + "</p>"]


def scene_section(name, ds, pictures=()) -> str:
    """One scene's section: a heading, then what the scene's kind has to say first."""
    kind = ds.attrs.get("scene_kind", "")
    parts = [f'<h2 id="scene-{html.escape(name)}">{KIND_TITLES.get(kind, "Scene")} {html.escape(name)}</h2>']
    if kind == "patient":
        parts += _patient(ds, [p for p in pictures if Path(p).stem.startswith("shape_")])
    elif kind == "synthetic":
        parts += ["<h3>Mean absolute parameter error over the runs</h3>",
                  table_html(error_table_with_units(ds), index=True)]
        parts += _pictures("Convergence", [p for p in pictures if Path(p).stem == "convergence"], "60%")
    else:
        parts += _pictures("Figures", pictures, "32%" if kind == "forward" else "60%")
    return "\n".join(parts)


def _kind_rank(scene):
    kind = scene[1].attrs.get("scene_kind", "")
    return KIND_ORDER.index(kind) if kind in KIND_ORDER else len(KIND_ORDER)


def front_page(scenes) -> str:
    """The page: ``scenes`` is a list of ``(name, summary dataset, PNG paths)``; patients first, then
    by kind in :data:`KIND_ORDER`, each kind in the order given."""
    body = [f"<style>{REPORT_LAYOUT_CSS}{TABLE_CSS}</style>",
            "<p>Each scene of this run, with what it found first; the categories on the left hold every "
            # not <code>: the report's prose style prints backticks around it
            "figure and table, and the datasets are in the results folder (read them with "
            '<span style="font-family:monospace">breastcore show</span>).</p>']
    body += [scene_section(name, ds, pictures) for name, ds, pictures in sorted(scenes, key=_kind_rank)]
    return "\n".join(body) + "\n"
