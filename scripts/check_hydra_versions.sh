#!/usr/bin/env bash
# decrun's translators of Hydra's and OmegaConf's error texts against every hydra-core and omegaconf
# release the dependency pins admit (pyproject.toml: hydra-core>=1.3.8,<1.4, omegaconf>=2.3,<2.4):
#
#     scripts/check_hydra_versions.sh [PYTHON]
#
# PYTHON (default: .venv/bin/python) is the environment decrun is installed in. For each admitted
# pair of versions (`pip index versions`, filtered by the pins) a fresh virtual environment gets that
# hydra-core and omegaconf (and the antlr4 they resolve to); the rest of decrun's
# dependencies are read from PYTHON's site-packages, placed after the fresh ones (a .pth file), so
# the fresh hydra-core and omegaconf are the ones imported. tests/runner/test_hydra_error_texts.py
# runs in each; the script prints one line per pair and exits 1 when one failed.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
PYTHON=${1:-$ROOT/.venv/bin/python}
# the pin of package $1 in pyproject.toml's dependencies (">=1.3.8,<1.4")
pin() {
  "$PYTHON" -c "
import tomllib
dependencies = tomllib.load(open('$ROOT/pyproject.toml', 'rb'))['project']['dependencies']
print(next(d[len('$1'):].strip() for d in dependencies if d.startswith('$1')))"
}
HYDRA_PIN=$(pin hydra-core)
OMEGACONF_PIN=$(pin omegaconf)
SITE=$("$PYTHON" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# the releases of package $1 that the pin $2 admits, oldest first
admitted() {
  "$PYTHON" -m pip index versions "$1" 2>/dev/null | sed -n 's/^Available versions: //p' | tr ',' '\n' |
    "$PYTHON" -c "
import sys
from packaging.specifiers import SpecifierSet
from packaging.version import Version
pin = SpecifierSet('$2')
print(' '.join(sorted((v for v in (line.strip() for line in sys.stdin) if v and v in pin), key=Version)))"
}
HYDRAS=$(admitted hydra-core "$HYDRA_PIN")
OMEGACONFS=$(admitted omegaconf "$OMEGACONF_PIN")
if [ -z "$HYDRAS" ] || [ -z "$OMEGACONFS" ]; then
  echo "no hydra-core release for $HYDRA_PIN or no omegaconf release for $OMEGACONF_PIN (is the package index reachable?)" >&2
  exit 2
fi

failed=0
for version in $HYDRAS; do
  for omegaconf in $OMEGACONFS; do
    venv="$WORK/hydra-$version-omegaconf-$omegaconf"
    log="$WORK/log-$version-$omegaconf"
    "$PYTHON" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "hydra-core==$version" "omegaconf==$omegaconf"
    fresh=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    echo "$SITE" > "$fresh/zz_decrun_dependencies.pth"
    imported=$("$venv/bin/python" -c 'import hydra, omegaconf; print(hydra.__version__, omegaconf.__version__)')
    if [ "$imported" != "$version $omegaconf" ]; then
      echo "hydra-core $version, omegaconf $omegaconf: the fresh environment imports $imported; not checked" >&2
      exit 2
    fi
    if (cd "$ROOT" && PYTHONPATH="$ROOT" MPLBACKEND=Agg "$venv/bin/python" -m pytest -q -p no:cacheprovider \
        tests/runner/test_hydra_error_texts.py > "$log" 2>&1); then
      echo "hydra-core $version, omegaconf $omegaconf: passed ($(tail -1 "$log"))"
    else
      echo "hydra-core $version, omegaconf $omegaconf: FAILED"
      tail -40 "$log"
      failed=1
    fi
  done
done
exit $failed
