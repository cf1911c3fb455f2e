"""Policy rules as plug-ins: each narrows the actions a greedy agent may take (:mod:`.base`).

An agent file stores its rules as an ordered list of names; :func:`make_rules` builds them, and
every result names them from that one list. A new rule is one module here and one line in
:data:`RULES`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from cpp_mujoco.agent.rules.base import Rule
from cpp_mujoco.agent.rules.finish_mask import FinishMask
from cpp_mujoco.agent.rules.progress_mask import ProgressMask
from cpp_mujoco.agent.rules.return_mask import ReturnMask
from cpp_mujoco.agent.rules.revisit_mask import RevisitMask
from cpp_mujoco.agent.rules.symmetric_q import SymmetricQ, SymmetricQUnseen
from cpp_mujoco.grid.way_home import ReturnMargin

# the rules by name, in the order an agent applies them (hard rules first, symmetric Q last)
RULES: dict[str, type] = {
    ReturnMask.name: ReturnMask,
    RevisitMask.name: RevisitMask,
    FinishMask.name: FinishMask,
    ProgressMask.name: ProgressMask,
    SymmetricQ.name: SymmetricQ,
    SymmetricQUnseen.name: SymmetricQUnseen,
}
# rules of which an agent takes one at most (each picks the action itself, last)
_EXCLUSIVE = ({SymmetricQ.name, SymmetricQUnseen.name},)
# the configs' booleans of the rules (agent files from before the rule list name them so; a
# rule born after the list has none)
RULE_FLAGS = {
    "return_mask": ReturnMask.name,
    "revisit_mask": RevisitMask.name,
    "finish_mask": FinishMask.name,
    "symmetric_q": SymmetricQ.name,
}

# the rules whose on/off every result records (the others only when on)
_ALWAYS_RECORDED = {ReturnMask.name, RevisitMask.name, FinishMask.name}


def check_rule_names(names: Iterable[str]) -> list[str]:
    """The names in :data:`RULES` order, each once; ``ValueError`` naming an unknown one."""
    names = list(names)
    unknown = sorted(set(names) - set(RULES))
    if unknown:
        raise ValueError(f"unknown rule {unknown[0]!r}; known: {', '.join(RULES)}")
    for group in _EXCLUSIVE:
        if len(group & set(names)) > 1:
            raise ValueError(f"rules {' and '.join(sorted(group))} exclude each other; give one")
    return [n for n in RULES if n in names]


def make_rules(
    names: Iterable[str], margin: ReturnMargin | None = None, own_orientation: Iterable[str] = ()
) -> list[Rule]:
    """The rules of ``names`` (in :data:`RULES` order); ``margin``: the return mask's in wind;
    ``own_orientation``: the digests of the maps the agent learned in their own orientation only
    (:func:`~cpp_mujoco.agent.rules.symmetric_q.own_orientation_maps`)."""
    made = {
        ReturnMask.name: lambda: ReturnMask(margin),
        SymmetricQUnseen.name: lambda: SymmetricQUnseen(own_orientation),
    }
    return [made.get(n, RULES[n])() for n in check_rule_names(names)]


def rule_names_of(stored: Mapping[str, Any]) -> list[str]:
    """The rule list an agent file's ``rules`` names; a file from before the list names its rules
    by booleans in its ``config`` (``return_mask``, ``revisit_mask``, ``finish_mask``,
    ``symmetric_q``): read as the same list."""
    if "rules" in stored:
        names = stored["rules"]
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ValueError(f"rules must be a list of rule names, got {names!r}")
        return check_rule_names(names)
    config = stored.get("config") or {}
    return [rule for flag, rule in RULE_FLAGS.items() if bool(config.get(flag, False))]


def rule_metadata(names: list[str]) -> dict[str, Any]:
    """What an agent's ``metadata`` says of its rules: the list, and each config flag."""
    return {"rules": list(names), **{flag: rule in names for flag, rule in RULE_FLAGS.items()}}


def rules_identity(rules: Iterable[Rule]) -> dict[str, Any]:
    """What results record of an agent's rules: for every rule with a config flag whether it is
    on (symmetric Q only when on, as results always had it; a rule born after the list only when
    on), and each rule's own identity."""
    by_name = {r.name: r for r in rules}
    out: dict[str, Any] = {}
    for name in RULES:
        rule = by_name.get(name)
        if name in _ALWAYS_RECORDED:
            out[name.replace("-", "_")] = rule is not None
        if rule is not None:
            out.update(rule.identity())
    return out


__all__ = [
    "RULES",
    "RULE_FLAGS",
    "FinishMask",
    "ProgressMask",
    "ReturnMask",
    "RevisitMask",
    "Rule",
    "SymmetricQ",
    "SymmetricQUnseen",
    "check_rule_names",
    "make_rules",
    "rule_metadata",
    "rule_names_of",
    "rules_identity",
]
