"""The twin and the diagnosis name the same effects: the diagnosis has one candidate term per
effect the twin can simulate (and nothing it cannot), under the same name, in the same order.
Only a test above both layers may import both (the diagnosis must not see the twin)."""
from __future__ import annotations

from delta6.diagnosis import terms
from delta6.twin import EFFECT_NAMES as TWIN_EFFECTS
from delta6.twin import REGISTRY


def test_the_diagnosis_has_a_term_for_every_twin_effect_and_no_other():
    assert terms.EFFECT_NAMES == TWIN_EFFECTS
    assert len(set(TWIN_EFFECTS)) == len(TWIN_EFFECTS) == len(REGISTRY)
    assert [t.name for t in terms.TERMS] == list(TWIN_EFFECTS)
