"""The inverse problem: measurements, the operator M(Λ) and its Jacobian, identification, uncertainty.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
