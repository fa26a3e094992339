"""MkDocs hook: turn the docstrings' Sphinx roles into cross-references.

The docstrings use ``:func:`name``` roles, which Markdown renders as
``:func:<code>name</code>``.  This hook drops the role and links the name
through mkdocs-autorefs when the object is documented on the site (an
*optional* reference: an unknown name stays plain code, with no warning).
Names without a leading ``undulate`` are looked up in the page's module.
"""

from __future__ import annotations

import html
import re

_ROLE = re.compile(r":(?:func|class|mod|meth|attr|data|exc|obj):<code>(~?)([^<]+)</code>")
_ROOT = re.compile(r'<h1 id="(undulate[\w.]*)"')


def on_page_content(html_text: str, page, **kwargs) -> str:
    root = _ROOT.search(html_text)
    module = root.group(1) if root else None

    def link(m: re.Match) -> str:
        tilde, name = m.group(1), html.unescape(m.group(2)).strip()
        bare = name.lstrip(".")
        title = bare.rsplit(".", 1)[-1] if tilde else name
        if bare.startswith("undulate"):
            identifier = bare
        elif module and not name.startswith("."):
            identifier = f"{module}.{bare}"
        else:
            return f"<code>{html.escape(title)}</code>"
        return (f'<autoref identifier="{html.escape(identifier)}" optional>'
                f"<code>{html.escape(title)}</code></autoref>")

    return _ROLE.sub(link, html_text)
