"""The ``breastcore`` command line: one module per sub-command, calling the stage functions.

This file imports nothing, so that it adds nothing to the code hash of a workflow stage
(:func:`breastcore.stage_hash`).
"""
