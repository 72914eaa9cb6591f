"""MkDocs hook, the safety net of docs/hooks/griffe_docstrings.py: a Sphinx role that reaches a
page's HTML anyway (``:func:<code>x</code>``, or ``:func:`x``` left in text) is shown as plain
code, so no API page prints a raw role. Code blocks (``<pre>``) are left as they are: a JSON
schema shows a description as the model gives it."""

from __future__ import annotations

import re
from typing import Any

ROLES = r"(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const|type)"
RENDERED = re.compile(rf":{ROLES}:(<code>)~?")
RAW = re.compile(rf":{ROLES}:`~?([^`<>]+)`")
PRE = re.compile(r"(<pre\b.*?</pre>)", re.S)


def on_page_content(html: str, page: Any, **kwargs: Any) -> str:
    parts = PRE.split(html)
    for i in range(0, len(parts), 2):  # the text between code blocks
        parts[i] = RAW.sub(r"<code>\1</code>", RENDERED.sub(r"\1", parts[i]))
    return "".join(parts)
