#!/usr/bin/env bash
# Create or reuse .venv and install hyst-gym with everything the demo and the tests need.
# Idempotent: re-runs pip only when pyproject.toml changed since the last successful install.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
stamp=".venv/.hyst-gym-setup"
want="$(sha256sum pyproject.toml scripts/setup.sh | sha256sum | cut -d' ' -f1)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi
.venv/bin/python -m pip install --quiet --upgrade pip
# torch first: a pinned CPU build where one is available locally, else any release in range.
if ! .venv/bin/python -c "import torch" 2>/dev/null; then
    .venv/bin/python -m pip install --quiet "torch==2.13.0" || .venv/bin/python -m pip install --quiet "torch>=2.3"
fi
.venv/bin/python -m pip install --quiet -e ".[rl,test,ray,docs,lint]"
echo "$want" > "$stamp"
