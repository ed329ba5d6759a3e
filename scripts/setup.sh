#!/usr/bin/env bash
# Idempotent setup: system packages (when missing), project-local .venv, project install.
# A second run on a ready machine only checks stamps and takes seconds.
set -euo pipefail
cd "$(dirname "$0")/.."

SYS_PKGS=(libllvm19 libegl1 libgl1-mesa-dri libegl-mesa0 libgl1 libglu1-mesa)
# Wait for a dpkg/apt lock another process holds (two setups at once, unattended upgrades)
# instead of failing on it.
APT=(apt-get -o DPkg::Lock::Timeout=600)
missing=()
for p in "${SYS_PKGS[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
        echo "[setup] installing system packages: ${missing[*]}"
        export DEBIAN_FRONTEND=noninteractive
        "${APT[@]}" update -qq >/dev/null
        "${APT[@]}" install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
    else
        echo "[setup] warning: missing system packages (${missing[*]}) and cannot apt-get; renderers may fall back" >&2
    fi
fi

# Headless Chromium checks the HTML report as a browser lays it out (tests skip without it).
if ! command -v chromium >/dev/null && [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "[setup] installing chromium (report layout tests)"
    (export DEBIAN_FRONTEND=noninteractive; "${APT[@]}" update -qq >/dev/null && \
        "${APT[@]}" install -y -qq --no-install-recommends chromium >/dev/null) \
        || echo "[setup] warning: could not install chromium; report layout tests will skip" >&2
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "[setup] creating .venv"
    "$PY" -m venv .venv
fi
# The Khronos glTF validator checks every GLB we write (tests, benchmarks); optional.
GLTF_VALIDATOR=gltf-validator@2.0.0-dev.3.10
if [ ! -d .venv/node/node_modules/gltf-validator ]; then
    if command -v npm >/dev/null; then
        echo "[setup] installing $GLTF_VALIDATOR into .venv/node"
        mkdir -p .venv/node
        npm install --silent --no-audit --no-fund --prefix .venv/node "$GLTF_VALIDATOR" >/dev/null 2>&1 \
            || echo "[setup] warning: could not install $GLTF_VALIDATOR; glTF validation tests will skip" >&2
    else
        echo "[setup] warning: npm not found; glTF validation tests will skip" >&2
    fi
fi

stamp=.venv/.mna-setup-stamp
want=$(cat pyproject.toml scripts/setup.sh | sha1sum | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    echo "[setup] .venv is up to date"
    exit 0
fi
echo "[setup] installing the project into .venv"
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
.venv/bin/python -m pip install -q "torch==2.13.0"
.venv/bin/python -m pip install -q -e ".[dev]"
echo "$want" > "$stamp"
echo "[setup] done"
