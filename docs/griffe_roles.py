"""Griffe extension of the API reference: Sphinx roles in docstrings become Markdown code spans.

The package's docstrings cite other objects as ``:class:`~bluesky_gym.core.Simulator``` or
``:meth:`Task.step```; the site shows them as ``Simulator`` and ``Task.step`` in code font.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:class|meth|func|attr|mod|data|obj|exc|const):`~?([^`]+)`")


def plain_roles(text: str) -> str:
    """Replace every Sphinx cross-reference role by a code span of its target (last part for ``~``)."""

    def span(match: re.Match[str]) -> str:
        target = match.group(1)
        shown = target.rsplit(".", 1)[-1] if match.group(0).split("`", 1)[1].startswith("~") else target
        return f"`{shown}`"

    return _ROLE.sub(span, text)


class SphinxRoles(griffe.Extension):
    """Rewrite the roles of every docstring as the objects are loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        """Rewrite ``obj``'s docstring."""
        if obj.docstring is not None:
            obj.docstring.value = plain_roles(obj.docstring.value)
