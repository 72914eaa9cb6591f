"""MkDocs hook, the safety net of docs/hooks/griffe_docstrings.py: a Sphinx role that reaches a
page's HTML anyway (``:func:<code>x</code>``, or ``:func:`x``` left in text) is shown as plain
code, so no API page prints a raw role."""

from __future__ import annotations

import re
from typing import Any

ROLES = r"(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const|type)"
RENDERED = re.compile(rf":{ROLES}:(<code>)~?")
RAW = re.compile(rf":{ROLES}:`~?([^`<>]+)`")


def on_page_content(html: str, page: Any, **kwargs: Any) -> str:
    html = RENDERED.sub(r"\1", html)
    return RAW.sub(r"<code>\1</code>", html)
