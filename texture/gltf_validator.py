"""The Khronos glTF validator (npm ``gltf-validator``, run by node) on a written GLB.

``make setup`` installs it into ``.venv/node`` when node and npm are present; tests that
need it skip with the reason when it is not there. Used by the tests and benchmarks to
check that what we write opens without errors or warnings in real viewers.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

#: where scripts/setup.sh installs the validator
NODE_PREFIX = Path(__file__).resolve().parents[1] / ".venv" / "node"

_SCRIPT = """
const validator = require('gltf-validator');
const fs = require('fs');
const data = new Uint8Array(fs.readFileSync(process.argv[1]));
validator.validateBytes(data, {maxIssues: 100})
  .then((r) => { process.stdout.write(JSON.stringify(r.issues)); })
  .catch((e) => { process.stderr.write(String(e)); process.exit(1); });
"""


def available() -> str | None:
    """None when the validator can run, else the reason it cannot."""
    if shutil.which("node") is None:
        return "node is not installed"
    if not (NODE_PREFIX / "node_modules" / "gltf-validator").is_dir():
        return f"gltf-validator is not installed under {NODE_PREFIX.name} (run make setup)"
    return None


def validate(path: str | os.PathLike) -> dict:
    """The validator's ``issues`` object for ``path``: ``numErrors``, ``numWarnings``, ``messages`` ..."""
    reason = available()
    if reason:
        raise RuntimeError(f"cannot run the glTF validator: {reason}")
    env = {**os.environ, "NODE_PATH": str(NODE_PREFIX / "node_modules")}
    proc = subprocess.run(["node", "-e", _SCRIPT, str(path)], capture_output=True, text=True, env=env, timeout=120)
    if proc.returncode != 0:
        raise RuntimeError(f"glTF validator failed on {path}: {proc.stderr.strip()[:300]}")
    return json.loads(proc.stdout)
