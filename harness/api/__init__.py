"""The public Python API, exported at the top of the package (``harness.prune`` ...; the README's "From Python").

One module per subject: :mod:`.scenes` (load, save, info, score, prune, methods), :mod:`.views`
(cameras), :mod:`.images` (render, compare), :mod:`.study` (evaluate). The commands of :mod:`harness.commands` are these
functions plus their flags and printing.
"""

from harness.api.images import compare, render
from harness.api.scenes import Pruned, info, load, methods, prune, save, score
from harness.api.study import evaluate
from harness.api.views import cameras

__all__ = ["Pruned", "cameras", "compare", "evaluate", "info", "load", "methods", "prune", "render", "save", "score"]
