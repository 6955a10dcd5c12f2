#!/usr/bin/env bash
# Runs every test: the Rust crate's lints (clippy, rustdoc, rustfmt), the documentation site (scripts/docs.sh,
# warnings as errors) and the crate's own tests, the Python linter and formatter (ruff, configured in pyproject.toml),
# then the Python suite against the built extension. Extra arguments go to pytest (e.g. -k soem). Exits non-zero when
# any test or check fails.
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
command -v cargo >/dev/null || { [[ -f "$HOME/.cargo/env" ]] && . "$HOME/.cargo/env"; }
[[ -x .venv/bin/pytest && -x .venv/bin/ruff ]] || { echo "test: .venv missing: run bash scripts/setup.sh first" >&2; exit 1; }

status=0
# The crate's lints, so CI holds the code to them: clippy (with and without the bindings),
# rustdoc with warnings denied (missing_docs is denied in lib.rs) and rustfmt.
lint() {
    echo "test: $*"
    (cd native && "$@") || status=1
}
lint cargo clippy --quiet --all-targets -- -D warnings
lint cargo clippy --quiet --all-targets --features python -- -D warnings
lint env RUSTDOCFLAGS="-D warnings" cargo doc --quiet --no-deps
lint env RUSTDOCFLAGS="-D warnings" cargo doc --quiet --no-deps --features python
lint cargo fmt --check
echo "test: scripts/docs.sh (the documentation site: rustdoc, then Sphinx with warnings as errors)"
bash scripts/docs.sh || status=1
echo "test: scripts/module_deps.py (no module cycle, no dependency up a layer, in the crate or the package)"
(cd scripts/module-deps && cargo fmt --check && cargo clippy --quiet --release -- -D warnings) || status=1
python3 scripts/module_deps.py || status=1
echo "test: cargo test (native/)"
# Tests that need CAP_NET_RAW are #[ignore]d so that cargo reports them as not run elsewhere.
cargo_args=()
((EUID == 0)) && cargo_args=(-- --include-ignored)
(cd native && cargo test --quiet "${cargo_args[@]}") || status=1
echo "test: ruff check, ruff format --check (the Python code, configured in pyproject.toml)"
.venv/bin/ruff check . || status=1
.venv/bin/ruff format --check . || status=1
echo "test: pytest (tests/)"
.venv/bin/pytest "$@" || status=1
if ((status)); then echo "test: FAILED" >&2; else echo "test: all passed"; fi
exit "$status"
