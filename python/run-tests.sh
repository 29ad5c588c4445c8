#!/usr/bin/env bash
# The Python package's checks, as .ci/run runs them: in a fresh virtual
# environment, `pip install ./python` (maturin builds the native module
# with cargo), the CLI the same-bits tests compare with, pytest, then the
# example notebook executed top to bottom (nbclient) so that it cannot rot.
#
# CARGO_TARGET_DIR (default: target of the checkout) is shared with the
# Rust build, so nothing cargo already built is built again. PYTHON picks
# the interpreter (default: python3). Needs network access to PyPI (or a
# warm pip cache) for maturin, numpy, pytest, OpenEXR and the notebook's
# packages.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_PROFILE_RELEASE_DEBUG=0 CARGO_TERM_COLOR=never
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$PWD/target}"
case "$CARGO_TARGET_DIR" in /*) ;; *) CARGO_TARGET_DIR="$PWD/$CARGO_TARGET_DIR" ;; esac
lap() { echo "   [${SECONDS} s since start]"; }

venv=$(mktemp -d)
trap 'rm -rf "$venv"' EXIT
echo "== a fresh virtual environment; pip install ./python (and the tests' packages)"
"${PYTHON:-python3}" -m venv "$venv"
"$venv/bin/pip" install -q ./python pytest OpenEXR matplotlib nbclient nbformat ipykernel
lap

# PENUMBRA_BIN: the CLI the same-bits tests compare with. .ci/run passes
# the one `cargo test --release` built (a plain `cargo build` would
# rebuild the tree: the tests' dev-dependencies change shared features).
if [ -z "${PENUMBRA_BIN:-}" ] || [ ! -x "$PENUMBRA_BIN" ]; then
  echo "== the CLI the same-bits tests compare with (cargo build --release)"
  cargo build --release --quiet --bin penumbra
  PENUMBRA_BIN="$CARGO_TARGET_DIR/release/penumbra"
  lap
fi

echo "== pytest python/tests"
# Run from the root with the venv's pytest: python/penumbra (the source,
# without the native module) is not on sys.path, the installed package is.
PENUMBRA_BIN="$PENUMBRA_BIN" "$venv/bin/pytest" -q -rs python/tests
lap

echo "== examples/soft-shadows.ipynb, executed (nbclient)"
(cd examples && "$venv/bin/python" - <<'PY'
import nbclient, nbformat
nb = nbformat.read("soft-shadows.ipynb", as_version=4)
nbclient.NotebookClient(nb, timeout=600, kernel_name="python3").execute()
print(f"executed {sum(c.cell_type == 'code' for c in nb.cells)} code cells")
PY
)
lap
