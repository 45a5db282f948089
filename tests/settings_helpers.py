"""What the settings tests read from a settings dataclass's source."""

from __future__ import annotations

import ast
import inspect
import textwrap


def field_docstrings(cls) -> dict[str, str]:
    """Every annotated field of the dataclass ``cls`` and the docstring that follows it in its
    source; an assertion error names a field with no docstring right after it."""
    body = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0].body
    docs = {}
    for field, after in zip(body, body[1:]):
        if isinstance(field, ast.AnnAssign):
            assert isinstance(after, ast.Expr) and isinstance(after.value.value, str), \
                field.target.id
            docs[field.target.id] = after.value.value
    return docs
