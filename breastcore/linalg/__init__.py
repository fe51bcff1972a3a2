"""Sparse linear algebra: the PARDISO runtime, factorizations (mixed precision), inertia.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
