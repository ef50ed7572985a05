/* Typeset every .math element with the KaTeX bundled into this file (no network).  The LaTeX
   source is the element's text, so without scripts the reader still sees it.  When done, the
   root element gets data-math="done" (or "failed") and data-math-count. */
(function () {
  "use strict";
  var root = document.documentElement;
  var nodes = document.querySelectorAll(".math");
  var failed = 0;
  if (typeof katex === "undefined") {
    console.error("KaTeX is missing from this file: the mathematics stays as LaTeX source");
    root.setAttribute("data-math", "failed");
    return;
  }
  for (var i = 0; i < nodes.length; i++) {
    var el = nodes[i];
    var tex = el.textContent;
    el.setAttribute("data-tex", tex);
    try {
      katex.render(tex, el, {
        displayMode: el.classList.contains("display"),
        throwOnError: true,
        strict: "warn",
        trust: false,
        maxSize: 50,
        output: "htmlAndMathml"
      });
      el.classList.add("typeset");
    } catch (err) {
      failed += 1;
      el.classList.add("math-error");
      el.textContent = tex;
      console.error("KaTeX could not typeset " + JSON.stringify(tex.slice(0, 120)) + ": " + err.message);
    }
  }
  root.setAttribute("data-math-count", String(nodes.length));
  root.setAttribute("data-math", failed ? "failed" : "done");
})();
