#!/usr/bin/env bash
# Writes the seed corpora of every fuzz target into corpus/<target>/ (see seed.py) from the
# real AKD's files: ../shared/real-akd/ beside the repository, or $REAL_AKD.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
real=${REAL_AKD:-$here/../../../shared/real-akd}
python3 "$here/seed.py" "$real" "$here/corpus"
