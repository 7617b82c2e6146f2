"""Sphinx extension of the rbbench docs: checked cross-references, whole summaries.

* Every Python cross-reference of the methods pages to ``rbbench`` or ``rbbench_plugins``
  must resolve: the
  methods pages name functions with roles such as ``{func}`rbbench.rb.algorithms.pod.pod```
  so that a renamed or moved function fails the build (``-W``) instead of leaving a dead
  name in the text. Sphinx ignores unresolved Python references unless ``nitpicky`` is
  set, which would also flag every type in every docstring; this check is limited to the
  project's own names.
* autosummary's first-sentence summary: Sphinx 9.0 cuts the summary at the first period
  followed by a space even inside an inline literal (its loop re-parses the whole stanza
  instead of the candidate sentence), which leaves ``"``a . b``"`` cut in two and an
  "Inline literal start-string without end-string" warning. The replacement below parses
  each candidate sentence, as the loop intends.
"""

from __future__ import annotations

from typing import Any

from docutils import nodes
from sphinx.util import logging

logger = logging.getLogger(__name__)

_PREFIXES = ("rbbench.", "rbbench_plugins.")
# the pages whose references are checked (docstrings name private helpers and constants that
# the API reference does not document)
_CHECKED_DOCS = ("methods/",)


def _extract_summary(doc: Any, settings: Any) -> str:
    from sphinx.ext import autosummary as asum

    first_stanza: list[str] = []
    for line in doc:
        blank = not line or line.isspace()
        if not first_stanza and blank:
            continue
        if blank:
            break
        first_stanza.append(line)
    if not first_stanza:
        return ""
    node = asum._parse_summary(first_stanza, settings)
    if isinstance(node[0], nodes.section):
        summary = node[0].astext().strip()
    elif not isinstance(node[0], nodes.paragraph):
        summary = first_stanza[0].strip()
    else:
        sentences = asum.periods_re.split(" ".join(first_stanza))
        summary = sentences[0].strip()
        if len(sentences) > 1:
            for i in range(len(sentences)):
                summary = ". ".join(sentences[: i + 1]).rstrip(".") + "."
                if summary.endswith(asum.WELL_KNOWN_ABBREVIATIONS):
                    continue
                parsed = asum._parse_summary([summary], settings)
                if not any(parsed.findall(nodes.system_message)):
                    break
    return asum.literal_re.sub(".", summary)


def _check_reference(app: Any, env: Any, node: Any, contnode: Any) -> None:
    if node.get("refdomain") != "py" or not node.get("refdoc", "").startswith(_CHECKED_DOCS):
        return None
    target = node.get("reftarget", "")
    if target.startswith(_PREFIXES) or target in ("rbbench", "rbbench_plugins"):
        logger.warning("unresolved reference to %s (no such documented object)", target,
                       location=node, type="rbbench", subtype="xref")
    return None


def setup(app: Any) -> dict[str, Any]:
    from sphinx.ext import autosummary

    autosummary.extract_summary = _extract_summary
    app.connect("missing-reference", _check_reference, priority=900)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
