// skewpend's module loader (a classic script).  The page's JavaScript -- three.js, the generated
// physics, the scene, the page's code -- arrives as text in classic scripts, each registering
// self.SKEWPEND_SOURCES[name] = {code, imports: {specifier: name}, classic}.  A module becomes a
// blob: URL with each of its import specifiers replaced by its dependency's blob: URL, so that the
// same files run from a web server, from the file system (file://, where browsers refuse to load
// module files) and inside a single HTML file (the report), and no request leaves the page.
//
// skewpend.import(name) -> the module; skewpend.source(name) -> a source's text (for Web Workers).
// The blob: URLs are kept page-wide, so a source registered once is one module however many times
// this script runs (each notebook widget's module runs it).
// When this script has data-entry="name", that module is imported once the page has parsed.
(function () {
  "use strict";
  const registry = (self.SKEWPEND_SOURCES = self.SKEWPEND_SOURCES || {});
  const urls = (self.SKEWPEND_URLS = self.SKEWPEND_URLS || {}); // page-wide: one module per source
  function source(name) {
    const entry = registry[name];
    if (!entry) throw new Error(`skewpend: no source named ${name}`);
    return entry.code;
  }
  function url(name, chain = []) {
    if (urls[name]) return urls[name];
    if (chain.includes(name)) throw new Error(`skewpend: circular imports ${chain.concat(name).join(" -> ")}`);
    let code = source(name);
    for (const [specifier, dep] of Object.entries(registry[name].imports || {})) {
      const target = url(dep, chain.concat(name));
      let found = 0;
      for (const q of ['"', "'"]) {
        const parts = code.split(`from ${q}${specifier}${q}`);
        found += parts.length - 1;
        code = parts.join(`from "${target}"`);
      }
      if (!found) throw new Error(`skewpend: ${name} does not import ${specifier}`);
    }
    urls[name] = URL.createObjectURL(new Blob([code], { type: "text/javascript" }));
    return urls[name];
  }
  const api = (self.skewpend = self.skewpend || {});
  api.source = source;
  api.import = (name) => import(url(name));
  const entry = document.currentScript && document.currentScript.dataset.entry;
  if (entry) {
    api.ready = api.import(entry).catch((err) => {
      console.error(err);
      const note = document.getElementById("notice");
      if (note) { note.textContent = `the page could not start: ${err.message}`; note.hidden = false; }
      throw err;
    });
  }
})();
