"""Run every ``python`` code block of the docs pages and of the README.

    python docs/run_python_blocks.py [FILE ...]

The blocks of one page run in order in one fresh interpreter, in a scratch directory (so
what they write goes nowhere near the checkout); a block that raises fails the page. Exit
status 1 if any page failed, with its output. Blocks fenced as ``python`` run; show code
that must not run as ``text`` or ``console``.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python\s*\n(.*?)^```\s*$", re.M | re.S)


def pages() -> list[Path]:
    """The README and the Markdown pages of ``docs/`` (not the generated or built ones)."""
    docs = [p for p in sorted((ROOT / "docs").rglob("*.md"))
            if not {"_build", "_generated"} & set(p.relative_to(ROOT / "docs").parts)]
    return [ROOT / "README.md", *docs]


def run_page(path: Path) -> tuple[bool, str, float, int]:
    """Run the page's blocks in one interpreter: ``(ok, output, seconds, blocks)``."""
    blocks = FENCE.findall(path.read_text())
    if not blocks:
        return True, "", 0.0, 0
    script = "\n\n".join(blocks)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="rbbench-blocks-") as work:
        out = subprocess.run([sys.executable, "-c", script], cwd=work, capture_output=True,
                             text=True, timeout=900)
    return out.returncode == 0, out.stdout + out.stderr, time.perf_counter() - t0, len(blocks)


def main(argv: list[str]) -> int:
    targets = [Path(a).resolve() for a in argv] or pages()
    failed = []
    for path in targets:
        ok, output, seconds, n = run_page(path)
        if n:
            print(f"{'ok  ' if ok else 'FAIL'} {path.relative_to(ROOT)}: {n} blocks, "
                  f"{seconds:.1f} s")
        if not ok:
            failed.append(path)
            print(output)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
