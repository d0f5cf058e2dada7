"""A Sphinx math renderer that writes MathML at build time (docutils' LaTeX-to-MathML
converter), so that formulas need no JavaScript and nothing from the network: browsers
render MathML Core natively. Configure with ``html_math_renderer = "mathml"``."""

from docutils import nodes
from docutils.utils.math import latex2mathml


def _inline(self, node):
    self.body.append(latex2mathml.tex2mathml(node.astext(), as_block=False))
    raise nodes.SkipNode


def _block(self, node):
    if node.get("label"):
        self.body.append(f'<span class="eqno">({node["number"]})</span>')
    parts = [p for p in node.astext().split("\n\n") if p.strip()]   # Sphinx's equation split
    self.body.append('<div class="math notranslate nohighlight">')
    self.body.extend(latex2mathml.tex2mathml(p, as_block=True) for p in parts)
    self.body.append("</div>")
    raise nodes.SkipNode


def setup(app):
    app.add_html_math_renderer("mathml", (_inline, None), (_block, None))
    return {"parallel_read_safe": True, "parallel_write_safe": True}
