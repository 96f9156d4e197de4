#!/usr/bin/env bash
# Set up everything the tests need (idempotent), run the checks, then the whole suite.
# The checks come first and any finding fails the run before a test starts: ruff (lint
# and format), mypy over core and the viewer, and import-linter's contracts: core never
# imports the viewer, Qt or a renderer, and the viewer's layers (pyproject.toml).
# Locally, BGM_SKIP_IMPORT_RULES=1 skips the import contracts; CI (which sets CI, see
# .ci/run) never skips them.
# Window tests need an X server: on Debian as root, xvfb and the xcb libraries
# Qt wants are installed when missing; elsewhere those tests skip.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[test]"
if ! command -v xvfb-run >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
     xvfb xauth libxcb-icccm4 libxcb-keysyms1 libxcb-image0 libxcb-render-util0 libxcb-cursor0 \
     libxkbcommon-x11-0 libxcb-xinerama0 libxcb-shape0 libgl1 libegl1 >/dev/null) \
  || echo "could not install xvfb; window tests will be skipped"
fi

failed=()
check() {
  local name=$1
  shift
  echo "== $name"
  "$@" || failed+=("$name")
}
check "ruff check" .venv/bin/ruff check core bgm_viewer tests
check "ruff format" .venv/bin/ruff format --check core bgm_viewer tests
check "mypy" .venv/bin/mypy core bgm_viewer
if [ -n "${BGM_SKIP_IMPORT_RULES:-}" ] && [ -z "${CI:-}" ]; then
  echo "== lint-imports skipped (BGM_SKIP_IMPORT_RULES is set)"
else
  check "lint-imports" .venv/bin/lint-imports
fi
if [ ${#failed[@]} -gt 0 ]; then
  echo "checks failed: ${failed[*]}" >&2
  exit 1
fi

export QT_API=pyside6
# One test process per core (CI has two); `-n 0` as an argument runs them in one process. Tests that share
# a costly module fixture are marked with one xdist_group, so one worker computes it, not each.
set -- -n "${BGM_TEST_WORKERS:-2}" --dist loadgroup "$@"
if command -v xvfb-run >/dev/null 2>&1; then
  exec xvfb-run -a -s "-screen 0 1280x1024x24" .venv/bin/python -m pytest -q "$@"
else
  exec .venv/bin/python -m pytest -q "$@"
fi
