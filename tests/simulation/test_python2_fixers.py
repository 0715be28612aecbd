"""Python 2 scripts run as Python 2 ran them: each idiom fissix leaves (python2_fixers.py), ported and run by
this Python 3, prints what Python 2.7.18 printed for the same script (recorded below from a real run), on the
same lines of the file. fissix's own fixes are checked the same way."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from dse_runner.simulation.python2 import as_python3

HEAD = "import codecs, csv, fileinput, io, json, os, string, sys, time\nd = {'a': 1}\n"
RESULTS = "time,level,valve\n0,1.0,0\n0.5,1.5,1\n1.0,2.0,1\n"  # results.csv, as the scripts find it

# (the script after HEAD, what Python 2.7.18 printed): every script has a print statement, so it is Python 2
AS_PYTHON2_RAN_THEM = [
    ("print [r['level'] for r in csv.DictReader(open('results.csv', 'rU'))]", "['1.0', '1.5', '2.0']"),
    ("print repr(open('results.csv', 'Ur').readline())", "'time,level,valve\\n'"),
    ("print repr(open('results.csv', 'U').readline())", "'time,level,valve\\n'"),
    ("print repr(open('results.csv', mode='rU').readline())", "'time,level,valve\\n'"),
    ("print io.open('results.csv', 'rU').readline().strip()", "time,level,valve"),
    ("print codecs.open('results.csv', 'rU', 'utf-8').readline().strip()", "time,level,valve"),
    ("print [line.strip() for line in fileinput.input('results.csv', mode='rU')][1]", "0,1.0,0"),
    ("print [r[1] for r in csv.reader(open('results.csv', 'rb'))]", "['level', '1.0', '1.5', '2.0']"),
    (
        "with open('o.csv', 'wb') as f:\n    csv.writer(f).writerow([1, 2])\n"
        + "print len(open('o.csv', 'rb').read())",
        "5",
    ),
    (
        "out = open('o.csv', 'wb')\nw = csv.DictWriter(out, ['a'])\nw.writerow({'a': 1})\nout.close()\n"
        + "print len(open('o.csv', 'rb').read())",
        "3",
    ),
    ("with open('o.json', 'wb') as f:\n    json.dump({'a': 1}, f)\nprint open('o.json').read()", '{"a": 1}'),
    ("print len(string.letters), string.lowercase[:3], string.uppercase[:3]", "52 abc ABC"),
    ("print 'abc'.translate(string.maketrans('a', 'b'))", "bbc"),
    (
        "print string.join(['a', 'b'], ','), string.join(['a', 'b']), string.joinfields(['a', 'b'], '-')",
        "a,b a b a-b",
    ),
    (
        "print string.split('a,b', ','), string.strip(' a '), string.replace('ab', 'a', 'c'), "
        + "string.upper('a' + 'b')",
        "['a', 'b'] a cb AB",
    ),
    ("print string.find('abc', 'c'), string.zfill('5', 3), string.splitfields('a b')", "2 005 ['a', 'b']"),
    ("print string.atof('1.5'), string.atoi('12'), string.atoi('ff', 16), string.atol('7')", "1.5 12 255 7"),
    ("print repr(file('results.csv').readline())", "'time,level,valve\\n'"),
    ("print cmp(1, 2), cmp('b', 'a'), sorted([1, 3, 2], cmp=lambda a, b: cmp(b, a))", "-1 1 [3, 2, 1]"),
    ("print type(time.clock()).__name__", "float"),
    ("x = 7\nx /= 2\nprint 7 / 2, -7 / 2, 7.0 / 2, 7 // 2, 2 * 7 / 4 * 2, x, True / 2", "3 -4 3.5 3 6 3 0"),
    (
        "print d.has_key('a'), type(os.getcwd()).__name__, sys.maxint > 2 ** 31",
        "True str True",
    ),  # fissix's own
]


def run(text: str, folder: Path) -> subprocess.CompletedProcess:
    (folder / "results.csv").write_text(RESULTS)
    (folder / "script.py").write_text(text)
    return subprocess.run(
        [sys.executable, "script.py"], cwd=folder, capture_output=True, text=True, timeout=60, check=False
    )


@pytest.mark.parametrize(("code", "printed"), AS_PYTHON2_RAN_THEM)
def test_a_python2_idiom_runs_as_python2_ran_it_on_the_same_lines(code, printed, tmp_path):
    script = HEAD + code + "\n"
    text, note = as_python3(script, tmp_path / "script.py")
    assert note is not None and "ported to Python 3 with fissix for this run" in note
    done = run(text, tmp_path)
    assert (done.stdout.strip(), done.stderr) == (printed, "")
    assert len(text.splitlines()) == len(script.splitlines())


def test_python2s_integer_division_holds_for_numpy_integers(tmp_path):
    """Python 2's NumPy divided integer arrays and scalars as Python 2 divided ints (classic division)."""
    script = (
        "import numpy\nhalves = numpy.array([7, 8]) / 2\n"
        + "print halves.tolist(), numpy.int64(7) / 2, numpy.array([7.0]) / 2\n"
    )
    done = run(as_python3(script, tmp_path / "script.py")[0], tmp_path)
    assert (done.stdout.strip(), done.stderr) == ("[3, 4] 3 [3.5]", "")


def test_a_traceback_names_the_users_line(tmp_path):
    """Statements the port adds (the division helper, fissix's ``from functools import reduce``) share a line
    with their neighbours: the ported script fails on the line the user's file has, also after a docstring,
    an emptied ``__future__`` import and functions defined before any import."""
    script = (
        '"""A metric."""\n'
        "from __future__ import print_function\n"
        "def half(x):\n"
        "    return x / 2\n"
        "import sys\n"
        "total = reduce(lambda a, b: a + b, [1, 2, 3])\n"
        "print(half(total), cmp(total, 0), file=sys.stderr)\n"
        "raise ValueError(unicode(half(7)))\n"
    )
    text, _ = as_python3(script, tmp_path / "script.py")
    done = run(text, tmp_path)
    assert done.stderr.splitlines()[0] == "3 1"  # Python 2's 6 / 2 and cmp
    assert 'script.py", line 8, in <module>' in done.stderr and done.stderr.endswith("ValueError: 3\n")
    assert len(text.splitlines()) == len(script.splitlines())


@pytest.mark.parametrize(
    ("script", "printed"),
    [
        ("import sys;\nprint 7 / 2\n", "3"),  # a statement that ends with its semicolon
        ("def half(x=7 / 2):\n    return x\nprint half()\n", "3"),  # a default value runs at the def
        ("if True:\n    print 7 / 2\n", "3"),  # nothing simple to share a line with: the helper's own line
    ],
)
def test_the_helpers_are_bound_before_the_script_first_divides(script, printed, tmp_path):
    done = run(as_python3(script, tmp_path / "script.py")[0], tmp_path)
    assert (done.stdout.strip(), done.stderr) == (printed, "")


def test_a_python2_script_that_defines_the_names_keeps_its_own(tmp_path):
    """A script's own cmp, a variable named string, and ``from __future__ import division`` are left alone."""
    script = (
        "from __future__ import division\n"
        "def cmp(a, b):\n"
        "    return 42\n"
        "string = 'a,b'\n"
        "print cmp(1, 2), 7 / 2, string.split(',')\n"
    )
    text, _ = as_python3(script, tmp_path / "script.py")
    assert (run(text, tmp_path).stdout, "_py2" in text) == ("42 3.5 ['a', 'b']\n", False)


def test_a_python3_script_gets_only_what_python_3_11_refuses(tmp_path):
    """A Python 3 script that opens its CSV with 'rU' (Python 3.10 accepted it) is run with 'r', and told so;
    its division stays Python 3's. One fissix cannot parse (a match statement) runs as written."""
    script = (
        "import csv, sys\n"
        "with open('results.csv', 'rU') as f:\n"
        "    rows = list(csv.DictReader(f))\n"
        "print(f'{len(rows)} rows', 7 / 2, file=sys.stdout)\n"
    )
    text, note = as_python3(script, tmp_path / "script.py")
    assert (
        note
        == "line 2: open mode 'rU' -> 'r' (Python 3.11 refuses 'U'); ported for this run, the file unchanged"
    )
    assert run(text, tmp_path).stdout == "3 rows 3.5\n"
    unparsed = "match = 1\nmatch match:\n    case 1:\n        pass\n"
    assert as_python3(unparsed, tmp_path / "script.py") == (unparsed, None)
    plain = "print(7 / 2)\n"
    assert as_python3(plain, tmp_path / "script.py") == (plain, None)
