"""The physics' transition names and the contract's are one set (sim_core cannot import
schemas: the physics knows nothing of the messages)."""

from __future__ import annotations

from typing import get_args

from schemas.result import TransitionKind as ContractKind
from sim_core.integrate.types import Event, TransitionKind
from sim_core.passage import TRANSITION_KINDS


def test_the_physics_and_the_contract_name_the_same_transitions() -> None:
    assert set(get_args(TransitionKind)) == set(get_args(ContractKind))
    assert tuple(e.label for e in Event) == TRANSITION_KINDS
    assert set(TRANSITION_KINDS) == set(get_args(TransitionKind))
    assert [TRANSITION_KINDS[int(e)] for e in Event] == [e.label for e in Event]
