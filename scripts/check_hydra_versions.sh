#!/usr/bin/env bash
# decrun's translators of Hydra's and OmegaConf's error texts against every hydra-core release the
# dependency pin admits (pyproject.toml: hydra-core>=1.3.8,<1.4):
#
#     scripts/check_hydra_versions.sh [PYTHON]
#
# PYTHON (default: .venv/bin/python) is the environment decrun is installed in. For each admitted
# hydra-core version (`pip index versions hydra-core`, filtered by the pin) a fresh virtual
# environment gets that hydra-core and the omegaconf and antlr4 it resolves to; the rest of decrun's
# dependencies are read from PYTHON's site-packages, placed after the fresh ones (a .pth file), so
# the fresh hydra-core and omegaconf are the ones imported. tests/runner/test_hydra_error_texts.py
# runs in each; the script prints one line per version and exits 1 when one failed.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
PYTHON=${1:-$ROOT/.venv/bin/python}
PIN='>=1.3.8,<1.4'
SITE=$("$PYTHON" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

VERSIONS=$("$PYTHON" -m pip index versions hydra-core 2>/dev/null | sed -n 's/^Available versions: //p' | tr ',' '\n' |
  "$PYTHON" -c "
import sys
from packaging.specifiers import SpecifierSet
pin = SpecifierSet('$PIN')
print(' '.join(v for v in (line.strip() for line in sys.stdin) if v and v in pin))")
if [ -z "$VERSIONS" ]; then
  echo "no hydra-core release found for $PIN (is the package index reachable?)" >&2
  exit 2
fi

failed=0
for version in $VERSIONS; do
  venv="$WORK/hydra-$version"
  "$PYTHON" -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "hydra-core==$version"
  fresh=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  echo "$SITE" > "$fresh/zz_decrun_dependencies.pth"
  omegaconf=$("$venv/bin/python" -c 'import omegaconf; print(omegaconf.__version__)')
  imported=$("$venv/bin/python" -c 'import hydra; print(hydra.__version__)')
  if [ "$imported" != "$version" ]; then
    echo "hydra-core $version: the fresh environment imports hydra-core $imported; not checked" >&2
    exit 2
  fi
  if (cd "$ROOT" && PYTHONPATH="$ROOT" MPLBACKEND=Agg "$venv/bin/python" -m pytest -q -p no:cacheprovider \
      tests/runner/test_hydra_error_texts.py > "$WORK/log-$version" 2>&1); then
    echo "hydra-core $version (omegaconf $omegaconf): passed ($(tail -1 "$WORK/log-$version"))"
  else
    echo "hydra-core $version (omegaconf $omegaconf): FAILED"
    tail -40 "$WORK/log-$version"
    failed=1
  fi
done
exit $failed
