"""The README's promises a geologist acts on: the column names it lists, the commands it shows."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def _readme() -> str:
    return README.read_text(encoding="utf-8")


def test_the_readme_names_every_column_name_bgm_finds():
    """A table with an `elev` or `label` column is read by name; the README listed neither, so a
    geologist renamed columns (or passed --z) that BGM would have found."""
    from core.io.blastholes import COLUMN_ALIASES

    text = " ".join(_readme().split())  # the list may wrap across lines
    for role, names in COLUMN_ALIASES.items():
        assert f"`{'/'.join(names)}`" in text, role


def _command_lines() -> list[list[str]]:
    """The `bgm ...` lines of the README's "Commands" block, optional parts' brackets removed."""
    block = _readme().split("### Commands", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    lines = []
    for line in block.splitlines():
        line = line.split("#", 1)[0].replace("[", " ").replace("]", " ").replace("|", " ")
        if line.strip().startswith("bgm "):
            lines.append(shlex.split(line)[1:])
    return lines


@pytest.mark.parametrize("words", _command_lines(), ids=lambda w: w[0])
def test_every_option_the_readme_shows_is_one_the_command_takes(words):
    import typer.main

    from core.cli import app, load_plugins

    load_plugins(app)  # `view` is the viewer's add-on command
    commands = typer.main.get_command(app).commands  # type: ignore[attr-defined]
    if words[0] not in commands:
        pytest.skip(f"bgm {words[0]} is an add-on not installed here")
    command = commands[words[0]]
    options = {o for p in command.params for o in (*p.opts, *p.secondary_opts)}
    shown = {w for w in words[1:] if w.startswith("--")}
    assert shown <= options, sorted(shown - options)


def test_the_readme_commands_name_geozones_of_the_kennecott_table(kennecott_csv):
    """The command lines' labels are Kennecott's (the README's `holes.csv`): `bgm suggest ... --geozone
    3310,3320` stopped with "geozone '3320' is not in holes.csv" on the table it was written from."""
    import pandas as pd

    present = set(pd.read_csv(kennecott_csv, usecols=["lookup_domain"])["lookup_domain"].astype(str))
    for words in _command_lines():
        for flag, value in zip(words, words[1:], strict=False):
            if flag == "--geozone":
                assert set(value.split(",")) <= present, (words[0], value)


def test_bgm_help_says_what_is_predicted_in_the_readmes_words():
    """`bgm --help` promised "slope predictions" (the paper's phrase); to a mine geologist a slope is a
    pit wall. The README's "a prediction below the deepest bench" is what the model gives."""
    from core.cli import app

    said = str(app.info.help)
    assert "below the deepest bench" in _readme() and "below the deepest bench" in said
    assert "slope" not in said
