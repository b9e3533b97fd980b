"""Packaging basics (issue 20, item 7) and the exit status shared by the subcommands
(item 3): ``pointax --version`` without JAX, a LICENSE matching pyproject's licence,
``py.typed`` shipped, a changelog, the pip route in the README; exit status 2 for bad
input from every subcommand.

References: pyproject.toml itself (tomllib), the MIT licence's own wording, and the
exit status documented in pointax.cli's docstring.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib

import pytest

from conftest import REPO

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())


def test_version_answers_without_jax():
    code = (
        "import sys\n"
        "from pointax.cli import main\n"
        "try:\n    main(['--version'])\nexcept SystemExit as e:\n    assert e.code == 0\n"
        "print('jax' in sys.modules, 'numpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.splitlines()[0] == f"pointax {PYPROJECT['project']['version']}"
    assert out.stdout.splitlines()[1] == "False False"


def test_license_file_matches_pyproject():
    licence = PYPROJECT["project"]["license"]["text"]
    assert licence == "MIT"
    text = (REPO / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "Permission is hereby granted, free of charge" in text


def test_py_typed_is_package_data():
    assert (REPO / "pointax" / "py.typed").is_file()
    assert "py.typed" in PYPROJECT["tool"]["setuptools"]["package-data"]["pointax"]


def test_changelog_and_pip_route():
    assert (REPO / "CHANGELOG.md").read_text().startswith("# Changelog")
    readme = (REPO / "README.md").read_text()
    assert "pip install ." in readme and 'pip install ".[vision]"' in readme
    assert "vision" in PYPROJECT["project"]["optional-dependencies"]


@pytest.mark.parametrize(
    "argv",
    [
        ["fit", "no-such-run.dat"],
        ["command", "no-such-directions.txt"],
        ["fit-network", "no-such-manifest.csv"],
        ["centroid", "no-such-frame.png"],
        ["compare", "no-such-run.dat", "--families", "basic"],
        ["fit", "run.dat", "--no-such-option"],
    ],
    ids=lambda a: a[0] + ("-option" if a[-1].startswith("--no") else ""),
)
def test_bad_input_exits_2_in_every_subcommand(argv, capsys):
    from pointax.cli import main

    try:
        status = main(argv)
    except SystemExit as exit:  # argparse's own errors
        status = exit.code
    assert status == 2
    err = capsys.readouterr().err
    assert "no-such" in err


def test_exit_status_is_documented_once():
    import pointax.cli

    doc = pointax.cli.__doc__
    assert "Exit status, the same for every subcommand" in doc
    assert "**0** success" in doc and "**1**" in doc and "**2** bad" in doc
