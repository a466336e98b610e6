#!/usr/bin/env bash
# Installs the zoo's robot data: the `example-robot-data` package of the Python package registry (the makers' URDFs
# and meshes of Panda, UR, Kinova, Z1, xArm, SO-100/101, Tiago, Talos, Baxter, ...), pinned, into a virtual
# environment under the target directory. Nothing is vendored in the repository; `assets/zoo.toml` names the arms and
# their URDF paths relative to the directory this script prints.
#
#   scripts/install_zoo.sh            # prints the package's robots directory (the `--zoo-dir` of convergence_domain)
#
# Idempotent: when the pinned version is already installed it only prints the directory. `--no-deps`: the package's
# declared dependencies (its CMake helpers) play no part in reading its files.
set -euo pipefail

VERSION=6.0.0
REPO=$(cd "$(dirname "$0")/.." && pwd)
VENV=${CARGO_TARGET_DIR:-$REPO/target}/zoo-venv
PYTHON=${PYTHON:-python3}

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV" >&2
fi
installed=$("$VENV/bin/python" -m pip show example-robot-data 2>/dev/null | sed -n 's/^Version: //p' || true)
if [ "$installed" != "$VERSION" ]; then
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
    "example-robot-data==$VERSION" >&2
fi
purelib=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
robots="$purelib/cmeel.prefix/share/example-robot-data/robots"
if [ ! -d "$robots" ]; then
  echo "install_zoo: example-robot-data $VERSION has no robots directory at $robots" >&2
  exit 1
fi
echo "$robots"
