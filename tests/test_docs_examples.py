"""The examples in the README and the docs still match the package: every ``undulate`` command in a shell
block parses (its subcommand, options and values, as click would take them), every option named in an
inline ``undulate ...`` span exists on its command, and every Python block parses, imports names that
exist and calls them with keywords they take.

A newcomer copies these first; an option renamed or an argument dropped in the code must fail here, not
on their machine.  Nothing is run (the examples simulate for seconds to minutes; the README's example and
the guides' studies are run by their own tests)."""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import shlex
from pathlib import Path

import pytest
import typer

from undulate.cli import app

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_SHELL_BLOCK = re.compile(r"^```(?:bash|console|sh|shell)\n(.*?)^```", re.S | re.M)
_PYTHON_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
_INLINE = re.compile(r"(?<!`)`(undulate [^`]+)`")
_PLACEHOLDER = re.compile(r"\[.*|.*\]|\.\.\.|…|[A-Z]+\.?\w*")  # [optional], EXPERIMENT..., DIR, NAME


def _rel(page: Path) -> str:
    return str(page.relative_to(ROOT))


def shell_commands() -> list[tuple[str, list[str]]]:
    """Every ``undulate ...`` command line in a shell block: (page, words after ``undulate``)."""
    found = []
    for page in PAGES:
        for block in _SHELL_BLOCK.findall(page.read_text(encoding="utf-8")):
            for line in block.replace("\\\n", " ").splitlines():
                line = re.split(r"\s#", " " + line.strip().removeprefix("$ "))[0]  # a trailing comment
                for part in re.split(r"&&|;|\|", line):
                    if "undulate" not in part:
                        continue
                    words = shlex.split(part)
                    if words[:1] == ["undulate"]:
                        found.append((_rel(page), [w for w in words[1:] if not re.fullmatch(r"\[.*|.*\]", w)]))
    return found


def inline_commands() -> list[tuple[str, list[str]]]:
    """Every inline ```undulate ...``` span (often a fragment: a command and some of its options)."""
    return [(_rel(page), span.split()[1:]) for page in PAGES
            for span in _INLINE.findall(page.read_text(encoding="utf-8"))]


def python_blocks() -> list[tuple[str, str]]:
    return [(_rel(page), block) for page in PAGES for block in _PYTHON_BLOCK.findall(page.read_text(encoding="utf-8"))]


def _resolve(words: list[str]):
    """The (sub)command the leading words name, its name, its parent context, and the words left (the
    click classes are typer's own, which bundles click)."""
    cmd, name, ctx = typer.main.get_command(app), "undulate", None
    while hasattr(cmd, "list_commands") and words and not words[0].startswith("-"):
        ctx = cmd.context_class(cmd, info_name=name, parent=ctx)
        sub = cmd.get_command(ctx, words[0])
        assert sub is not None, f"no command {words[0]!r} under {name!r}"
        name, cmd, words = words[0], sub, words[1:]
    return cmd, name, ctx, words


def test_the_pages_hold_examples():
    """The collectors find what is there (a regex that matched nothing would pass every test below)."""
    assert len(shell_commands()) >= 30
    assert len(inline_commands()) >= 50
    assert len(python_blocks()) >= 8
    assert any(words[:1] == ["reproduce"] for _, words in shell_commands())


@pytest.mark.parametrize(("page", "words"), shell_commands(), ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_shell_command_parses(page, words):
    cmd, name, ctx, rest = _resolve(list(words))
    assert not hasattr(cmd, "list_commands"), f"{page}: undulate {' '.join(words)}: names no command"
    try:
        cmd.make_context(name, list(rest), parent=ctx)  # parses and converts every option; runs nothing
    except typer.TyperException as e:
        pytest.fail(f"{page}: undulate {' '.join(words)}: {e.format_message()}")


@pytest.mark.parametrize(("page", "words"), inline_commands(), ids=lambda v: v if isinstance(v, str) else " ".join(v))
def test_inline_command_names_options_that_exist(page, words):
    words = [w for w in words if not _PLACEHOLDER.fullmatch(w) or w.startswith("-")]
    cmd, name, _, rest = _resolve(words)
    known = {"--help"} | {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}
    unknown = [w.split("=")[0] for w in rest if w.startswith("--") and w.split("=")[0] not in known]
    assert not unknown, f"{page}: `undulate {' '.join(words)}`: {name} has no {', '.join(unknown)}"


def _imported(tree: ast.Module) -> dict[str, object]:
    """The local names the block imports from ``undulate`` and the objects they are (AssertionError if one
    does not exist)."""
    names: dict[str, object] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "undulate":
            module = importlib.import_module(node.module)
            for alias in node.names:
                assert hasattr(module, alias.name), f"{node.module} has no {alias.name}"
                names[alias.asname or alias.name] = getattr(module, alias.name)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "undulate":
                    importlib.import_module(alias.name)
    return names


def _bad_keywords(tree: ast.Module, names: dict[str, object]) -> list[str]:
    bad = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in names):
            continue
        target = names[node.func.id]
        if not callable(target):
            continue
        try:
            params = inspect.signature(target).parameters
        except (TypeError, ValueError):
            continue
        if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
            continue
        bad += [f"{node.func.id}({k.arg}=...)" for k in node.keywords if k.arg is not None and k.arg not in params]
    return bad


@pytest.mark.parametrize(("page", "source"), python_blocks(), ids=lambda v: v if len(v) < 60 else None)
def test_python_block_uses_the_api_as_it_is(page, source):
    tree = ast.parse(source)
    names = _imported(tree)
    assert not _bad_keywords(tree, names), f"{page}: {_bad_keywords(tree, names)}"


def test_the_checks_catch_drift():
    """A renamed option, an unknown subcommand, a wrong keyword and a missing name each fail."""
    cmd, name, ctx, rest = _resolve(["simulate", "--phase", "0,90"])
    assert name == "simulate"
    with pytest.raises(typer.TyperException, match="No such option"):
        cmd.make_context(name, rest, parent=ctx)
    cmd, name, ctx, rest = _resolve(["simulate", "--links", "two"])
    with pytest.raises(typer.TyperException, match="valid integer"):
        cmd.make_context(name, rest, parent=ctx)
    assert _resolve(["robot", "run", "--port", "x"])[1] == "run"
    with pytest.raises(AssertionError, match="no command"):
        _resolve(["simulat"])
    tree = ast.parse("from undulate import Scene\nScene(phase_rad=(0.0,))\n")
    assert _bad_keywords(tree, _imported(tree)) == ["Scene(phase_rad=...)"]
    with pytest.raises(AssertionError, match="has no Scenery"):
        _imported(ast.parse("from undulate import Scenery\n"))
