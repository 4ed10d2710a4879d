"""Guide pages from Markdown to safe HTML, maths included, on the server.

Teachers write Markdown with maths (``$…$`` inline, ``$$…$$`` display) and
images. :func:`render_markdown` parses it with markdown-it-py (CommonMark,
tables, the dollarmath plugin), turns each formula into MathML with
latex2mathml, and passes the whole page through nh3 (Ammonia) with an allow
list: no ``<script>``, no ``on…=`` attribute, no ``style``, and only
``http``, ``https`` and ``mailto`` links (relative ones too; ``data:`` only as
a PNG/JPEG/GIF/WebP image's source), so nothing a teacher writes runs in a
student's browser. The lab's Content-Security-Policy (``img-src 'self' data:``)
shows images served by the lab or embedded as ``data:``; others are blocked.

Why MathML on the server: every current browser draws MathML Core natively,
so maths needs no JavaScript, no font and no CDN (the lab works offline), and
the sanitiser sees the final markup.
"""

from __future__ import annotations

import html
import re

import nh3
from latex2mathml.converter import convert as latex_to_mathml
from markdown_it import MarkdownIt
from mdit_py_plugins.dollarmath import dollarmath_plugin

__all__ = ["MAX_MARKDOWN_CHARS", "render_markdown"]

MAX_MARKDOWN_CHARS = 30_000
"""The longest guide section accepted (characters of Markdown; the lab's 64 KiB body limit
holds it even with every character escaped in JSON as two bytes or more)."""

_MATHML_TAGS = {
    "math", "semantics", "annotation", "mrow", "mi", "mn", "mo", "ms", "mtext", "mspace",
    "msup", "msub", "msubsup", "mfrac", "msqrt", "mroot", "mover", "munder", "munderover",
    "mtable", "mtr", "mtd", "mstyle", "mpadded", "mphantom", "menclose", "merror",
}  # fmt: skip
_HTML_TAGS = {
    "p", "br", "hr", "h1", "h2", "h3", "h4", "h5", "h6", "strong", "em", "del", "s", "code",
    "pre", "blockquote", "ul", "ol", "li", "a", "img", "table", "thead", "tbody", "tr", "th",
    "td", "span", "div", "sup", "sub",
}  # fmt: skip
_MATHML_ATTRIBUTES = {
    "display", "mathvariant", "stretchy", "fence", "separator", "accent", "accentunder",
    "lspace", "rspace", "width", "height", "depth", "columnalign", "rowspacing",
    "columnspacing", "linethickness", "displaystyle", "scriptlevel", "encoding", "form",
    "largeop", "movablelimits", "symmetric", "minsize", "maxsize", "notation",
}  # fmt: skip
_ATTRIBUTES: dict[str, set[str]] = {
    "a": {"href", "title"},
    "img": {"src", "alt", "title", "width", "height"},
    "th": {"align"},
    "td": {"align"},
    "ol": {"start"},
    "code": {"class"},
    "div": {"class"},
    "span": {"class"},
    **{tag: set(_MATHML_ATTRIBUTES) for tag in _MATHML_TAGS},
}
_URL_SCHEMES = {"http", "https", "mailto", "data"}
# The page's Content-Security-Policy lets images come from the lab itself or as
# data: URLs, so a guide's pictures are relative links or small embedded images;
# data: is kept only there, and only for raster images (never in a link).
_DATA_IMAGE = re.compile(r"^data:image/(png|jpeg|gif|webp);base64,[A-Za-z0-9+/=\s]+$")


def _keep_attribute(tag: str, attribute: str, value: str) -> str | None:
    if attribute in ("href", "src") and value.strip().lower().startswith("data:"):
        keep = tag == "img" and attribute == "src" and _DATA_IMAGE.match(value.strip())
        return value if keep else None
    return value


def _formula(latex: str, options: dict[str, bool]) -> str:
    display = options.get("display_mode", False)
    try:
        mathml: str = latex_to_mathml(latex, display="block" if display else "inline")
    except Exception:
        mathml = f'<code class="math-error">{html.escape(latex)}</code>'
    return mathml


def _parser() -> MarkdownIt:
    # "js-default" is CommonMark plus tables and strikethrough; raw HTML stays
    # allowed (teachers may write a <sub>), the sanitiser keeps only the safe part.
    md = MarkdownIt("js-default", {"html": True, "linkify": False, "typographer": False})
    md.use(
        dollarmath_plugin,
        allow_labels=False,
        allow_space=True,
        allow_digits=True,
        double_inline=True,
        renderer=_formula,
    )
    return md


_MARKDOWN = _parser()


def render_markdown(markdown: str) -> str:
    """Return the sanitised HTML of a guide section written in Markdown.

    Parameters
    ----------
    markdown : str
        CommonMark with tables, ``$…$``/``$$…$$`` maths (LaTeX, drawn as
        MathML) and images (``![alt](https://…)``).

    Returns
    -------
    str
        HTML safe to insert in a page: no scripts, event handlers, styles,
        frames or ``javascript:`` URLs; ``data:`` only as a raster image's source.

    Examples
    --------
    >>> render_markdown("**K** = $x^2$ <img src=x onerror=alert(1)>")[:20]
    '<p><strong>K</strong'
    """
    raw = _MARKDOWN.render(markdown)
    cleaned: str = nh3.clean(
        raw,
        tags=_HTML_TAGS | _MATHML_TAGS,
        attributes=_ATTRIBUTES,
        url_schemes=_URL_SCHEMES,
        link_rel="noopener noreferrer nofollow",
        attribute_filter=_keep_attribute,
        strip_comments=True,
    )
    return cleaned
