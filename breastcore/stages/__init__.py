"""One module per workflow stage: read inputs, call breastcore, write one dataset.

The Snakemake scripts in ``workflow/scripts`` are thin wrappers around these, so every
stage can also be run (and tested) without Snakemake. Each stage imports only what it
uses: its rule's code hash (:func:`breastcore.source_hash`) covers those modules, so an
edit of one stage's code reruns that stage and the ones that import it, not every job.
This file imports nothing, so that it adds nothing to any stage's hash.
"""
