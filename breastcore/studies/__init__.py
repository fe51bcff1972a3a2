"""Studies beyond one identification: stability, extreme guesses, the Chassaignac calibration.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
