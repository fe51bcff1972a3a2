"""Tables as HTML for Snakemake's report, which shows an HTML result in the page and offers a CSV
one only as a download (issue #22)."""

from __future__ import annotations

import html

import pandas as pd

#: The style of every table the report shows (the front page's and each table page's).
TABLE_CSS = """
table.breastcore { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.95em; }
table.breastcore th, table.breastcore td { border: 1px solid #bbb; padding: 3px 8px; text-align: right; }
table.breastcore th { background: #eee; }
table.breastcore td:first-child, table.breastcore th:first-child { text-align: left; }
"""


def table_html(frame: pd.DataFrame, index: bool = False) -> str:
    """``frame`` as one ``<table class="breastcore">`` (4 significant digits), in a box that
    scrolls sideways when the table is wider than the page."""
    table = frame.to_html(index=index, border=0, classes="breastcore", float_format=lambda v: f"{v:.4g}",
                          na_rep="—", justify="center")
    return f'<div class="breastcore-table">{table}</div>'


def table_page(frame: pd.DataFrame, title: str, index: bool = False) -> str:
    """A standalone HTML page of ``frame`` under the heading ``title``."""
    title = html.escape(title)
    return (f"<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>"
            f"<style>body {{ font-family: system-ui, sans-serif; margin: 1em; }}{TABLE_CSS}</style></head>\n"
            f"<body><h2>{title}</h2>\n{table_html(frame, index)}</body></html>\n")


def write_table(frame: pd.DataFrame, csv_path, html_path, title: str, index: bool = False) -> None:
    """Write ``frame`` as CSV (the data) and as an HTML page (what the report shows), each atomically."""
    from breastcore.io.datasets import write_text

    write_text(frame.to_csv(index=index), csv_path)
    write_text(table_page(frame, title, index), html_path)
