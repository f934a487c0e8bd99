"""Every case of the bad-input corpus (``corpus.py``), run as the user would: the command line
exits with the case's status, prints its words in one line on stderr and no traceback, and
writes nothing but the case's own inputs; each misuse of the Python API raises the case's
exception with its words, or returns the right value."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from corpus import API_CASES, CASES, api_context

from jaxtrack.cli import main


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("case", [pytest.param(c, id=c.name, marks=[pytest.mark.slow] if c.slow else []) for c in CASES])
def test_command_line_case(case, tmp_path, capsys):
    argv = case.build(tmp_path)
    inputs = _files(tmp_path)
    capsys.readouterr()
    try:
        status = main(argv)
    except SystemExit as exit_:  # argparse: usage and one error line
        status = exit_.code
    captured = capsys.readouterr()
    assert status == case.status, captured.err
    assert "Traceback" not in captured.err + captured.out
    if case.status == 0:
        return
    last = captured.err.strip().splitlines()[-1]
    assert last.startswith(f"jaxtrack {argv[0]}: error: "), captured.err
    assert all(word in last for word in case.words), last
    assert _files(tmp_path) == inputs  # nothing written, no temporary file left


@pytest.fixture(scope="module")
def context(tmp_path_factory):
    return api_context(tmp_path_factory.mktemp("api"))


@pytest.fixture
def as_a_user_runs_it():
    """The suite checks every annotation at run time (jaxtyping); a user's Python does not, and
    the API's own messages are what this corpus checks."""
    import jaxtyping

    jaxtyping.config.update("jaxtyping_disable", True)
    yield
    jaxtyping.config.update("jaxtyping_disable", False)


@pytest.mark.parametrize("case", API_CASES, ids=lambda c: c.name)
def test_python_api_case(case, context, as_a_user_runs_it):
    if case.error is None:
        assert case.check(case.call(context), context)
        return
    with pytest.raises(case.error) as raised:
        case.call(context)
    assert all(word in str(raised.value) for word in case.words), str(raised.value)


def test_the_corpus_writes_its_files_and_list(tmp_path):
    """``python tests/bad_inputs/corpus.py OUT`` writes every fast case's inputs and cases.json."""
    import json

    from corpus import main as write_corpus

    assert write_corpus([str(tmp_path), "--fast"]) == 0
    listing = json.loads((tmp_path / "cases.json").read_text())
    assert [c["case"] for c in listing] == [c.name for c in CASES if not c.slow]
    assert all(c["argv"][0] == "jaxtrack" for c in listing)
