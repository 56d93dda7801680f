"""The side programs users run are ``tdem`` subcommands (issue 26: one entry point): ``tdem
window`` (tdem_post.window), ``tdem paper-compare`` (tdem_post.paper_compare) and ``tdem
fft-reference`` (tdem_post.fft_conductivity). Each takes its module's own options (the module's
``add_arguments``) and does its module's work (``command``), so the subcommand and the module
give the same output; ``python -m <module>`` still parses the same options."""
import importlib
import json
import re

import pytest

from tdem.cli import build_parser, main

COMMANDS = {"window": "tdem_post.window", "paper-compare": "tdem_post.paper_compare",
            "fft-reference": "tdem_post.fft_conductivity"}


def _subparser(name):
    parser = build_parser()
    for action in parser._actions:          # (argparse has no public list of them)
        if hasattr(action, "choices") and isinstance(action.choices, dict) \
                and name in action.choices:
            return action.choices[name]
    raise AssertionError(f"tdem has no subcommand {name!r}")


def _options(parser):
    """(option strings or dest, default, required) of every argument but --help."""
    return sorted((tuple(a.option_strings) or (a.dest,), repr(a.default), a.required)
                  for a in parser._actions if a.dest != "help")


@pytest.mark.parametrize("name", COMMANDS)
def test_subcommand_takes_the_module_options(name, capsys):
    import argparse
    module = importlib.import_module(COMMANDS[name])
    own = argparse.ArgumentParser()
    module.add_arguments(own)
    sub = _subparser(name)
    assert _options(sub) == _options(own)
    assert len(_options(own)) >= 3
    with pytest.raises(SystemExit) as e:
        main([name, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith(f"usage: tdem {name}")
    for action in own._actions:
        for option in action.option_strings:
            assert option in text, (name, option)
    # the module's own entry (python -m) parses the same options
    with pytest.raises(SystemExit) as e:
        module.main(["--help"])
    assert e.value.code == 0
    module_help = capsys.readouterr().out
    for action in own._actions:
        for option in action.option_strings:
            assert option in module_help, (name, option)


def _window_json(case, pressure_pa, gamma_case, gamma_window):
    case.mkdir(parents=True)
    (case / "window.json").write_text(json.dumps({
        "case": str(case), "law": "pipe", "pressure_pa": pressure_pa,
        "gamma_case": gamma_case, "gamma_window": gamma_window,
        "gamma_paper_window": None if gamma_window is None else gamma_window * 1.9,
        "gamma_steady": gamma_case * 1.07,
        "not_measurable": {} if gamma_window is not None else {"gamma": "the window is early"},
    }))


def test_window_prints_what_the_module_prints(tmp_path, capsys):
    """A case whose window.json exists is printed from it (not run again): the subcommand's
    lines are the module's, character for character."""
    from tdem_post import window
    a, b = tmp_path / "cases" / "1e+05Pa_pipe", tmp_path / "cases" / "4e+05Pa_pipe"
    _window_json(a, 1.00796e5, 0.011881439, 0.012062481)
    _window_json(b, 3.99e5, 0.0201, None)
    capsys.readouterr()
    assert main(["window", str(a), str(b)]) == 0
    via_tdem = capsys.readouterr().out
    assert window.main([str(a), str(b)]) == 0
    via_module = capsys.readouterr().out
    assert via_tdem == via_module
    lines = via_tdem.splitlines()
    assert lines[0].startswith("p (bar)  law")
    assert "0.01188" in lines[1] and "0.01206" in lines[1] and "0.02292" in lines[1]
    assert "n/m" in lines[2] and "gamma not measurable: the window is early" in lines[3]


def test_fft_reference_prints_what_the_module_prints(capsys):
    """Two small grids, one rule: the same table (seconds masked) by both paths, its numbers
    those of docs/fft_reference.md at n 8 and 12."""
    from tdem_post import fft_conductivity
    argv = ["--grids", "8,12", "--rules", "laminate"]
    capsys.readouterr()
    assert main(["fft-reference", *argv]) == 0
    via_tdem = capsys.readouterr().out
    assert fft_conductivity.main(argv) == 0
    via_module = capsys.readouterr().out

    def masked(text):
        return re.sub(r" +[0-9.]+ s$", " <s>", text, flags=re.MULTILINE)
    assert masked(via_tdem) == masked(via_module)
    assert "Rayleigh k/k_m 1.482412" in via_tdem
    assert "n    8: k/k_m 1.487985" in via_tdem and "n   12: k/k_m 1.485389" in via_tdem


def test_paper_compare_draws_what_the_module_draws(tmp_path, capsys):
    """A three-pressure campaign's results.csv: the subcommand writes the figure plot() writes
    (the same PNG bytes) and says where."""
    from tdem_post import paper_compare
    out = tmp_path / "campaign"
    out.mkdir()
    rows = ["law,pressure_pa,gamma_paper,tau_s"] + [
        f"{law},{p},{0.02 * (p / 1e5) ** 0.36},{40 * (p / 1e5) ** -0.37}"
        for law in ("pipe", "bob") for p in (2.8e4, 4e5, 1.6e6)]
    (out / "results.csv").write_text("\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["paper-compare", str(out), "-o", str(tmp_path / "a.png")]) == 0
    assert capsys.readouterr().out == f"wrote {tmp_path / 'a.png'}\n"
    paper_compare.plot(out, tmp_path / "b.png")
    data = (tmp_path / "a.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert data == (tmp_path / "b.png").read_bytes()
