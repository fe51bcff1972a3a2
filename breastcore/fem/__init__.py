"""The finite-element energy: the material law, pointwise kernels, compiled loops, energy terms, assembly.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
