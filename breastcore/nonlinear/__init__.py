"""Nonlinear solvers: Newton with line search, nonlinear CG, saddle escape.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
