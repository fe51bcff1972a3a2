"""The report: scene summaries, tables, figures, the results page, the paper's values.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
