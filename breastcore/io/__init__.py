"""Datasets: the netCDF files of every stage, patients, mesh export.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
