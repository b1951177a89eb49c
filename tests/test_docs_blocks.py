"""Every example block of README.md and docs/*.md runs, from a clean checkout, with ``fusion``.

The convention (docs/README.md, "Examples in these pages"): every ```bash, ```console and
```python block is run, in the order of its page, in one temporary folder per page that holds
links to the repository's ``tests/``, ``examples/`` and ``benchmarks/`` (the data the examples
read), with ``fusion`` and ``python`` on the PATH. A block whose first line is
``# not run in CI: <reason>`` is shown to the reader but not run; the reason is required. A block
may not change a file an earlier block of its page wrote (examples do not overwrite each other's
outputs), and no block may write into the repository. Commands shown without a language
(```` ``` ```` followed by ``fusion ...``) are refused: they would escape the check.
"""

from __future__ import annotations

import os
import re
import stat
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUN_LANGUAGES = ("bash", "console", "python")
NOT_RUN = re.compile(r"^#\s*not run in CI:\s*(.*)$")
FENCE = re.compile(r"^```([\w-]*)\n(.*?)^```", flags=re.S | re.M)
#: Repository folders the examples read, linked into each page's folder.
LINKED = ("tests", "examples", "benchmarks")
#: Repository folders no block may write into (the data and scripts the examples read).
GUARDED = ("tests/data", "examples")
#: Longest a single block may take, s (the whole file stays near two minutes on 2 cores).
BLOCK_TIMEOUT_S = 240


@dataclass(frozen=True)
class Block:
    page: Path
    line: int
    language: str
    text: str

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    def not_run_reason(self) -> str | None:
        first = self.text.strip().splitlines()[0] if self.text.strip() else ""
        m = NOT_RUN.match(first.strip())
        return None if m is None else m.group(1).strip()


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a Markdown page, in order."""
    text = page.read_text(encoding="utf-8")
    return [Block(page, text[:m.start()].count("\n") + 1, m.group(1), m.group(2))
            for m in FENCE.finditer(text)]


def _console_commands(text: str) -> str:
    """The commands of a console transcript: lines starting with ``$ `` (and their ``\\``
    continuations)."""
    out, cont = [], False
    for line in text.splitlines():
        if line.startswith("$ ") or cont:
            line = line[2:] if line.startswith("$ ") else line
            out.append(line)
            cont = line.rstrip().endswith("\\")
    return "\n".join(out)


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """path -> (mtime_ns, size) of every file under `folder`, not following the links."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = [d for d in dirnames if d != "__pycache__"
                       and not os.path.islink(os.path.join(dirpath, d))]
        for name in filenames:
            path = os.path.join(dirpath, name)
            st = os.lstat(path)
            if stat.S_ISREG(st.st_mode):
                out[os.path.relpath(path, folder)] = (st.st_mtime_ns, st.st_size)
    return out


def _tools(bin_dir: Path) -> None:
    """``fusion`` (the installed one beside this interpreter, else ``python -m fusion``) and
    ``python`` (this interpreter) in `bin_dir`."""
    bin_dir.mkdir()
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    (bin_dir / "python").chmod(0o755)
    installed = Path(sys.executable).parent / "fusion"
    launcher = bin_dir / "fusion"
    if installed.is_file() and not os.environ.get("PYTHONPATH"):
        launcher.symlink_to(installed)
    else:  # a development run: the package on PYTHONPATH, through this interpreter
        launcher.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m fusion "$@"\n')
        launcher.chmod(0o755)


def _run(block: Block, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    if block.language == "python":
        argv = [sys.executable, "-c", block.text]
    else:
        script = block.text if block.language == "bash" else _console_commands(block.text)
        argv = ["bash", "-euo", "pipefail", "-c", script]
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=BLOCK_TIMEOUT_S)


def test_pages_found():
    assert ROOT / "README.md" in PAGES and len(PAGES) > 5


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_commands_are_marked_and_reasons_given(page):
    """A command shown without a language, or a not-run block without its reason, is refused."""
    for b in blocks(page):
        first = b.text.lstrip().split(" ", 1)[0] if b.text.strip() else ""
        assert not (b.language == "" and first in ("fusion", "python", "python3")), (
            f"{b.where}: a command block must say its language (```bash), or start with "
            "'# not run in CI: <reason>'")
        if b.language in RUN_LANGUAGES and b.not_run_reason() is not None:
            assert b.not_run_reason(), f"{b.where}: '# not run in CI:' needs a reason"


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_page_blocks_run(page, tmp_path):
    """The page's runnable blocks run in order in one folder, none changing another's output."""
    runnable = [b for b in blocks(page) if b.language in RUN_LANGUAGES and b.not_run_reason() is None]
    if not runnable:
        pytest.skip("no runnable block")
    work = tmp_path / "work"
    work.mkdir()
    for name in LINKED:
        (work / name).symlink_to(ROOT / name, target_is_directory=True)
    _tools(tmp_path / "bin")
    env = {**os.environ, "PATH": f"{tmp_path / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
           "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    repo_before = {name: _snapshot(ROOT / name) for name in GUARDED}
    for b in runnable:
        before = _snapshot(work)
        r = _run(b, work, env)
        assert r.returncode == 0, (f"{b.where} ({b.language}) failed, exit {r.returncode}:\n"
                                   f"{b.text}\n--- stderr:\n{r.stderr[-3000:]}")
        after = _snapshot(work)
        changed = sorted(p for p, sig in before.items() if after.get(p, sig) != sig)
        assert not changed, f"{b.where}: overwrote the output of an earlier block: {changed}"
    for name in GUARDED:
        now = _snapshot(ROOT / name)
        changed = sorted(p for p in {*now, *repo_before[name]}
                         if now.get(p) != repo_before[name].get(p))
        assert not changed, f"a block of {page.name} wrote into {name}/: {changed}"
