"""Run docs/quickstart.md's commands as written, and check (or rewrite) the outputs the page shows.

The page is a user's first contact, so it must not drift from what the tool prints. Its ``console``
blocks hold ``$ dse-runner …`` lines, each followed by the command's standard output; a line ``...``
stands for lines left out. Its ``yaml``/``python`` blocks whose first line is ``# jobs/…`` show that
file whole. Run in a fresh copy of the folders the page uses, so earlier results are never reused:

    python docs/quickstart_page.py            # check: exit 1 and say where the page and the tool differ
    python docs/quickstart_page.py --write    # rewrite the page's outputs from a fresh run

tests/project/test_quickstart.py runs the check. Timings, sizes and absolute paths differ between runs and
are compared as placeholders; every other number within 2 % (fits converge to a tolerance, not a bit).
"""

from __future__ import annotations

import argparse
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PAGE = REPO / "docs" / "quickstart.md"
COPIED = ("jobs/quickstart", "jobs/msd/fmus")  # what the page's commands read, copied into the fresh folder
SKIP = "..."
VOLATILE = [  # (pattern, placeholder): what changes from run to run
    (re.compile(r"\b\d+(\.\d+)? s on \d+ workers"), "T s on N workers"),
    (re.compile(r"utilisation \d+% of"), "utilisation P% of"),
    (re.compile(r"\(\d+(\.\d+)? [kMG]?B\)"), "(SIZE)"),
]
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
RELATIVE = 0.02


@dataclass
class Step:
    """One ``$`` command of the page and the output shown under it."""

    command: str
    shown: list[str]
    line: int  # where the command stands in the page


def steps(text: str) -> list[Step]:
    """The page's commands, in order, with their shown outputs."""
    found: list[Step] = []
    inside = False
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            inside = line.strip() == "```console"
            continue
        if not inside:
            continue
        if line.startswith("$ "):
            found.append(Step(line[2:], [], number))
        elif found:
            found[-1].shown.append(line)
    return found


FILE_BLOCK = re.compile(r"(```(?:yaml|python)\n# (jobs/\S+)\n)(.*?)(```)", flags=re.DOTALL)


def shown_files(text: str) -> dict[str, str]:
    """Files the page shows whole: a yaml or python block whose first line is ``# jobs/...``."""
    return {match.group(2): match.group(3) for match in FILE_BLOCK.finditer(text)}


def with_files(text: str) -> str:
    """The page with every file it shows as the file is now."""
    return FILE_BLOCK.sub(lambda m: m.group(1) + (REPO / m.group(2)).read_text() + m.group(4), text)


def normal(line: str, root: Path) -> str:
    """A line with the fresh folder's path made relative and the volatile parts as placeholders."""
    line = line.replace(f"{root}/", "").rstrip()
    for pattern, placeholder in VOLATILE:
        line = pattern.sub(placeholder, line)
    return line


def same(shown: str, printed: str) -> bool:
    """The same words, and numbers within ``RELATIVE`` (or 1e-3) of each other."""
    if NUMBER.sub("#", shown) != NUMBER.sub("#", printed):
        return False
    return all(
        abs(float(a) - float(b)) <= max(1e-3, RELATIVE * abs(float(b)))
        for a, b in zip(NUMBER.findall(shown), NUMBER.findall(printed))
    )


def differences(shown: list[str], printed: list[str]) -> list[str]:
    """Where the shown lines are not the printed ones in order (``...`` skips any number of lines)."""
    at = 0
    problems = []
    skipping = False
    for line in shown:
        if line.strip() == SKIP:
            skipping = True
            continue
        match = (
            next((k for k in range(at, len(printed)) if same(line, printed[k])), None)
            if skipping
            else (at if at < len(printed) and same(line, printed[at]) else None)
        )
        if match is None:
            instead = printed[at] if at < len(printed) else "(nothing more)"
            problems.append(f"shown {line!r}, printed {instead!r}")
            break
        at, skipping = match + 1, False
    if not skipping and at < len(printed) and not problems:
        problems.append(f"printed more than shown, from {printed[at]!r} (end the block with ... if meant)")
    return problems


def fresh_folder() -> Path:
    """A new folder holding copies of what the page reads, laid out as in the repository."""
    root = Path(tempfile.mkdtemp(prefix="dse-quickstart-"))
    for part in COPIED:
        shutil.copytree(REPO / part, root / part, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def run(command: str, root: Path) -> subprocess.CompletedProcess:
    """The command as a user types it: ``dse-runner`` the installed command, in the fresh folder."""
    words = shlex.split(command)
    if words[0] == "dse-runner":
        words[0] = str(Path(sys.executable).with_name("dse-runner"))
    return subprocess.run(words, check=False, cwd=root, capture_output=True, text=True)


def check(text: str, root: Path) -> list[str]:
    """Every difference between the page and a fresh run of its commands; the shown files too."""
    problems = [
        f"{path}: the page shows another text than the file"
        for path, body in shown_files(text).items()
        if (REPO / path).read_text() != body
    ]
    for step in steps(text):
        done = run(step.command, root)
        if done.returncode != 0:
            said = done.stderr.strip()[-400:]
            problems.append(f"line {step.line}: {step.command}: exit {done.returncode}: {said}")
            continue
        printed = [normal(line, root) for line in done.stdout.splitlines()]
        problems.extend(
            f"line {step.line}: {step.command}: {p}"
            for p in differences([normal(s, root) for s in step.shown], printed)
        )
    return problems


def rewritten(text: str, root: Path) -> str:
    """The page with each command's shown output replaced by a fresh run's, whole (shorten by hand with
    ``...``)."""
    text = with_files(text)
    lines = text.splitlines()
    out: list[str] = []
    by_line = {step.line: step for step in steps(text)}
    skipping_until_next = False
    for number, line in enumerate(lines, 1):
        if number in by_line:
            out.append(line)
            done = run(by_line[number].command, root)
            out.extend(printed.replace(f"{root}/", "").rstrip() for printed in done.stdout.splitlines())
            skipping_until_next = True
            continue
        if skipping_until_next and (line.startswith(("$ ", "```"))):
            skipping_until_next = False
        if not skipping_until_next:
            out.append(line)
    return "\n".join(out) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the page's outputs from a fresh run")
    args = parser.parse_args()
    root = fresh_folder()
    try:
        if args.write:
            PAGE.write_text(rewritten(PAGE.read_text(), root))
            print(f"rewrote {PAGE}")
            return
        problems = check(PAGE.read_text(), root)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    for problem in problems:
        print(problem)
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
