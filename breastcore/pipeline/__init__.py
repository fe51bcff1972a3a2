"""The workflow's job plan, config checks, keys, logs and runner (the Snakefile builds on these).

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
