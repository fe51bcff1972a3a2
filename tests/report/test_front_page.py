"""The report's first page and its HTML tables (issue #22): a patient's verdict, estimate with
intervals and measured against fitted in clinical units, then the pictures; patients first."""

import base64
import re

import numpy as np
import pandas as pd
import xarray as xr

from breastcore.report.front_page import front_page
from breastcore.report.html_tables import table_page, write_table
from test_clinical import _patient_summary

# a 1×1 PNG
PNG = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==")


def _rows(table_html):
    return [re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", row, re.S) for row in re.findall(r"<tr[^>]*>(.*?)</tr>", table_html, re.S)]


def test_a_patient_section_gives_verdict_estimate_fit_and_inlined_pictures(tmp_path):
    picture = tmp_path / "shape_standing.png"
    picture.write_bytes(PNG)
    page = front_page([("p", _patient_summary(), [str(picture)])])
    assert "Patient p</h2>" in page and "Fit verdict: consistent" in page
    tables = re.findall(r"<table.*?</table>", page, re.S)
    assert len(tables) == 2
    estimate = {row[0]: row for row in _rows(tables[0])[1:]}
    assert estimate["R"][1:5] == ["56.2", "mm", "50.58", "61.82"]                      # mm, its 95 % interval
    assert estimate["lambda_breast"][3] == "—" and "not determined" in estimate["lambda_breast"][5]
    fit = {(row[0], row[1]): row for row in _rows(tables[1])[1:]}
    assert fit[("standing", "volume")][2:6] == ["ml", "601", "607", "1"]              # ml, +1 %
    assert fit[("standing", "area")][2:5] == ["cm²", "250", "252.5"]
    assert fit[("fours", "height")][2] == "mm" and fit[("fours", "height")][-1] == "yes"
    assert f"data:image/png;base64,{base64.b64encode(PNG).decode()}" in page       # the report stays one file


def test_patients_come_first_whatever_the_config_order():
    synthetic = xr.Dataset(attrs={"scene_kind": "forward"})
    page = front_page([("demo", synthetic, []), ("p", _patient_summary(), [])])
    assert "<code>" not in page          # Snakemake's report style wraps inline code in literal backticks
    assert page.index("Patient p") < page.index("Forward solve demo")


def test_a_table_is_written_as_csv_data_and_as_an_html_page(tmp_path):
    frame = pd.DataFrame({"parameter": ["R", "H"], "estimate (mm)": [56.2, np.nan]})
    write_table(frame, tmp_path / "t.csv", tmp_path / "t.html", "Identified <parameters>")
    assert pd.read_csv(tmp_path / "t.csv").equals(frame)
    page = (tmp_path / "t.html").read_text()
    assert page == table_page(frame, "Identified <parameters>")
    assert "<h2>Identified &lt;parameters&gt;</h2>" in page
    assert _rows(page) == [["parameter", "estimate (mm)"], ["R", "56.2"], ["H", "—"]]
