#!/usr/bin/env bash
# Builds the documentation site into docs/_build/html and prints the page to open in a browser: the crate's rustdoc
# (cargo doc, with the bindings) copied to rustdoc/ beside the pages, then Sphinx with warnings as errors, so a
# broken link or cross-reference, a page in no table of contents or a docstring Sphinx cannot read fails it.
# scripts/test.sh runs it. Needs .venv (bash scripts/setup.sh).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
command -v cargo >/dev/null || { [[ -f "$HOME/.cargo/env" ]] && . "$HOME/.cargo/env"; }
[[ -x .venv/bin/sphinx-build ]] || { echo "docs: .venv has no sphinx-build: run bash scripts/setup.sh first" >&2; exit 1; }

out=docs/_build/html
(cd native && RUSTDOCFLAGS="-D warnings" cargo doc --quiet --no-deps --features python)
.venv/bin/sphinx-build -q -W --keep-going -b html docs "$out"
rm -rf "$out/rustdoc"
cp -r native/target/doc "$out/rustdoc"
[[ -f $out/rustdoc/akd_native/index.html ]] || { echo "docs: rustdoc has no akd_native/index.html" >&2; exit 1; }
echo "docs: open $PWD/$out/index.html"
