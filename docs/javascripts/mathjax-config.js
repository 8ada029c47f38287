// MathJax 3, served from the site (docs/hooks/mathjax_assets.py copies it in): typeset only
// the TeX that pymdownx.arithmatex marked, \( \) inline and \[ \] displayed.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true,
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex",
  },
};
