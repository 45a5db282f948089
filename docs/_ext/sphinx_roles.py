"""A Griffe extension for the API reference: the docstrings' Sphinx roles as inline code.

The docstrings are numpy style and cite objects with Sphinx roles (``:class:`~topomap.Trajectory```,
``:meth:`fit```), which Markdown would show as written. This rewrites each role as inline code of
its target (the last name only with ``~``), at collection time; the source is untouched.
"""

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|meth|func|mod|data|attr|obj|exc|const):`(~?)([^`]+)`")


def _code(match: re.Match) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


class SphinxRoles(griffe.Extension):
    """Rewrite ``:role:`target``` in every docstring as ```target```."""

    def on_instance(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None and ":`" in obj.docstring.value:
            obj.docstring.value = ROLE.sub(_code, obj.docstring.value)
