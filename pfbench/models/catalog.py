"""What ``pfbench models`` lists: per registered model its description, dimensions and which of
the structured methods (mpf, guided, kalman) it supports.

Support is read from what the model declares, the way the filters themselves check it, without
running anything: ``mpf`` needs a conditionally linear-Gaussian substructure
(:func:`pfbench.filters.marginalized._declares_structure`), ``kalman`` that substructure holding
every state, ``guided`` a valid ``proposal_kind`` (:func:`pfbench.filters.guided.proposal_kind`).
The particle methods need only the four model functions. Values are those of the model at its
default parameters.
"""
from __future__ import annotations

import re
import sys

from ..errors import PfbenchError


def description(cls) -> str:
    """The first sentence of the model class's own docstring, or of its module's where the class
    has none or its docstring opens with the parameters ("" if neither has one)."""
    for doc in (cls.__dict__.get("__doc__"), getattr(sys.modules.get(cls.__module__), "__doc__", None)):
        para = " ".join((doc or "").strip().split("\n\n")[0].split())
        if para and not para.startswith("Parameters"):
            # a sentence ends at '.' or ':' before a capital, a quote or the end ("eq. 6" does not)
            return re.split(r"(?<=[.:])\s+(?=[A-Z`])|::", para, maxsplit=1)[0].rstrip(".:")
    return ""


def supported(model) -> dict[str, bool]:
    """Whether ``model`` (an instance) declares what methods mpf, guided and kalman need."""
    from ..filters.guided import proposal_kind
    from ..filters.marginalized import _declares_structure
    from .contract import linear_indices

    mpf = _declares_structure(model)
    try:
        proposal_kind(model)
        guided = True
    except PfbenchError:
        guided = False
    try:  # a malformed linear_states (an int, say) supports neither, as the filters refuse it
        kalman = mpf and linear_indices(model).size == int(model.n_x)
    except PfbenchError:
        mpf = kalman = False
    return {"mpf": mpf, "guided": guided, "kalman": kalman}


def describe(name: str) -> dict:
    """One row of ``pfbench models``: name, description, n_x, n_y, n_u and the supported methods."""
    from . import get, model_class

    cls = model_class(name)
    model = get(name)
    return {"name": name, "description": description(cls), "n_x": int(model.n_x), "n_y": int(model.n_y),
            "n_u": int(model.n_u), "supports": supported(model)}
