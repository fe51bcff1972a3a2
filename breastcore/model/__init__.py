"""The model: parameters (the one source of defaults, units and bounds), postures, geometry, mesh.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
