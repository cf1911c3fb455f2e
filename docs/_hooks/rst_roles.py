"""A griffe extension for the API reference: the docstrings' reStructuredText roles
(``:class:`~cpp_mujoco.grid.mdp.GridMDP` ``) as Markdown code spans (`GridMDP`), the name as
Sphinx would show it (a leading ``~`` keeps the last component)."""

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const|ref):`(~?)([^`]+)`")


def _span(match: re.Match) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


class RstRoles(griffe.Extension):
    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_span, obj.docstring.value)
