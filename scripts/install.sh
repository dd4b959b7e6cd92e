#!/usr/bin/env bash
# Creates (or reuses) the virtual environment given as $1 (default .venv) and installs the project into it.
# torch==2.13.0 goes first: a plain `torch` requirement on a machine without torch would pull a CUDA build of several GB.
set -euo pipefail
venv="${1:-.venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q --upgrade pip
# A torch already in the venv (e.g. a CPU or CUDA build of your choice, >= 2.3) is kept.
"$venv/bin/python" -c "import torch" 2>/dev/null || "$venv/bin/python" -m pip install -q "torch==2.13.0"
# hub, notebook, track and docs: what the tests of push-to-hub/load-from-hub, the notebook, train --track and the
# documentation's build need (CI runs them)
"$venv/bin/python" -m pip install -q -e ".[tests,zoo,postgres,hub,notebook,track,docs]"
