// Typesets the formulas pymdownx.arithmatex (generic mode) leaves in the page: inline ones as
// <span class="arithmatex">\(...\)</span>, display ones as <div class="arithmatex">\[...\]</div>.
// KaTeX is vendored under javascripts/katex/ (nothing is loaded from a CDN).
(function () {
  function typeset(root) {
    if (typeof katex === "undefined") return;
    root.querySelectorAll(".arithmatex").forEach(function (el) {
      if (el.dataset.katex === "done") return;
      var tex = el.textContent.trim();
      var display = el.tagName === "DIV";
      if (tex.startsWith("\\(") || tex.startsWith("\\[")) tex = tex.slice(2, -2);
      else if (tex.startsWith("$$")) tex = tex.slice(2, -2);
      else if (tex.startsWith("$")) tex = tex.slice(1, -1);
      try {
        katex.render(tex, el, { displayMode: display, throwOnError: false });
        el.dataset.katex = "done";
      } catch (err) {
        console.error(err);
      }
    });
  }
  if (typeof document$ !== "undefined") {
    // mkdocs-material's instant navigation swaps the page body: typeset each new one
    document$.subscribe(function (doc) { typeset(doc.body || document.body); });
  } else {
    document.addEventListener("DOMContentLoaded", function () { typeset(document.body); });
  }
})();
