"""Run ``scripts/migrate_0_1_0.py`` as a user would: a separate Python process."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "migrate_0_1_0.py"

#: What the package says of a file or store written by 0.1.0 (then the path).
REFUSAL = r"written by youbot_opt 0\.1\.0 \(schema \d\); run `python scripts/migrate_0_1_0\.py "


def migrate(*args: str | Path, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the migration script with ``args``; return the finished process (output captured)."""
    return subprocess.run(
        [sys.executable, str(SCRIPT), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=cwd,
    )
