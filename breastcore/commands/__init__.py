"""Sub-commands of the ``breastcore`` command line, one module each."""

from . import browse, export, identify, measure, sensitivity, solve

#: Each entry registers one sub-command on an argparse sub-parser collection.
REGISTRY = [solve.register, export.register, measure.register, identify.register, sensitivity.register, browse.register]
