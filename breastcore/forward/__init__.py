"""The forward model: the equilibrium of one posture, and several postures in parallel.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
