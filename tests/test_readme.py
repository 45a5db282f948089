"""Every ``topomap`` command in the README and in the documentation pages does what its text says.

The commands are read from the fenced code blocks of ``README.md`` and ``docs/*.md``, so the text
and the code cannot drift: each one (every job of a sweep) must compose and pass every check that
can be made before data is simulated, and a command whose comment says it is ``rejected`` must be
refused; the single-run examples of the Configuration page and the first sweep example of the
Sweeps page run end to end (shortened to a few hundred steps). The README keeps its two commands,
and ``.ci/run`` runs the test command verbatim, then builds the documentation site strictly.
"""

import itertools
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from topomap.app.compose.command_line import overrides_of, plugins_named
from topomap.app.run.experiment import make_learner, run
from topomap.app.compose.registry import Registry

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = [README, *sorted(DOCS.glob("*.md"))]
#: the README's two commands: install and run the paper's experiment; install and run the tests
TWO_COMMANDS = ['pip install -e . && topomap', 'pip install -e ".[test]" && python -m pytest']
#: commands whose text says that some jobs cannot run, and how many
DOCUMENTED_FAILURES = {"topomap experiment=sweep_pricai2002": 15}
#: commands that run a plugin the page installs first (``pip install -e .``): tested with the
#: plugin's module listed instead, which registers the same components the entry point does
INSTALLED_PLUGINS = {"topomap stop=max_splits stop.k=3": "my_stop.py"}
#: what a command needs beyond the test extras: it is checked only where the package is installed
OPTIONAL = {"env=minigrid": "minigrid", "minigrid_empty": "minigrid", "env=arena": "ratinabox",
            "arena_two_rooms": "ratinabox", "rat_tanni": "ratinabox",
            "hydra/sweeper=optuna": "hydra_plugins.hydra_optuna_sweeper",
            "hydra/launcher=ray": "hydra_plugins.hydra_ray_launcher"}
#: a run shortened for the test (appended, so it wins over the page's own values)
SHORT = ["data.n_steps=200", "data.heldout_steps=0", "output.figures=false",
         "output.progress=false"]


def fenced_lines(path, section=None):
    """``(line, comment)`` of every line in the fenced code blocks of a page, optionally of its
    ``## section`` only."""
    text = path.read_text()
    if section is not None:
        text = text[text.index(f"## {section}"):]
        text = text[:text.index("\n## ", 1)] if "\n## " in text[1:] else text
    for block in re.findall(r"^```[\w-]*\n(.*?)^```", text, re.S | re.M):
        for line in block.splitlines():
            code = line.split(" # ")[0].split("  #")[0]
            yield code.strip(), line[len(code):].strip().lstrip("#").strip()


def page_commands(path=README, section=None, with_comments=False):
    """``topomap ...`` lines of a page's code blocks (comments stripped)."""
    commands = []
    for line, comment in fenced_lines(path, section):
        if line.startswith("topomap ") and "..." not in line and "<" not in line:
            commands.append((line, comment) if with_comments else line)
    return commands


def readme_commands(section=None):
    return page_commands(README, section)


def documented_commands():
    """Every distinct command of the README and the pages: ``(command, comment, page)``, the
    first page that shows it."""
    seen = {}
    for page in PAGES:
        for command, comment in page_commands(page, with_comments=True):
            seen.setdefault(command, (command, comment, page.relative_to(ROOT).as_posix()))
    return list(seen.values())


def code_files():
    """The files the pages' code blocks define: a block whose first line is ``# name.py`` (or, for
    a floor plan, ``# name.yaml``)."""
    files = {}
    for page in PAGES:
        for block in re.findall(r"^```(?:python|yaml)\n(.*?)^```", page.read_text(), re.S | re.M):
            first = block.splitlines()[0]
            if re.fullmatch(r"# [\w/]+\.(py|yaml)", first):
                files[first[2:]] = block
    return files


def sweep_values(value: str) -> list[str]:
    """The values a swept override stands for: ``a,b,c``; ``choice(a,b)``; ``range(a,b[,s])``; a
    search space ``interval(a,b)`` (``int(...)``: an integer one) stands for its middle."""
    value = value.strip()
    space = re.fullmatch(r"(int\()?\s*interval\(\s*([-\d.]+)\s*,\s*([-\d.]+)\s*\)\)?", value)
    if space:
        middle = (float(space[2]) + float(space[3])) / 2
        return [str(int(middle)) if space[1] else str(middle)]
    call = re.fullmatch(r"(choice|range)\((.*)\)", value)
    if call and call[1] == "range":
        return [str(v) for v in range(*(int(x) for x in call[2].split(",")))]
    return [v.strip() for v in (call[2] if call else value).split(",")]


def jobs_of(command, make_cfg):
    """The composed config of every job a command runs (a sweep expanded; a search space at its
    middle)."""
    args = shlex.split(command)[1:]
    swept, fixed = [], []
    for o in overrides_of(args):
        key, _, value = o.partition("=")
        if "-m" in args and "," in value and not value.startswith("["):
            swept.append((key, sweep_values(value)))
        else:
            fixed.append(o)
    params = OmegaConf.select(make_cfg(fixed, hydra=True), "hydra.sweeper.params") or {}
    swept += [(k, sweep_values(str(v))) for k, v in params.items()]
    for combo in itertools.product(*(values for _, values in swept)) if swept else [()]:
        job = fixed + [f"{k}={v}" for (k, _), v in zip(swept, combo)]
        yield job, make_cfg([o for o in job if not o.startswith("hydra")])


def test_the_readme_keeps_its_two_commands_and_ci_runs_the_test_command_verbatim():
    lines = [line for line, _ in fenced_lines(README, "Two commands")]
    assert lines == TWO_COMMANDS
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    tests = ci.index(TWO_COMMANDS[1])
    assert any("mkdocs build --strict" in line for line in ci[tests + 1:])


def test_the_readme_and_the_pages_have_commands():
    assert len(readme_commands()) >= 10
    assert len(documented_commands()) >= 30
    assert len(page_commands(DOCS / "configuration.md")) >= 5
    assert all(page_commands(page) for page in (DOCS / "getting-started.md", DOCS / "exploring.md",
                                                DOCS / "worlds.md", DOCS / "sweeps.md"))


def compose_checked(command, make_cfg):
    """Compose every job of ``command`` and run the checks made before data is simulated; the
    jobs that fail them, with their messages."""
    for needs, module in OPTIONAL.items():
        if needs in command:
            pytest.importorskip(module)
    failed = []
    for job, cfg in jobs_of(command, make_cfg):
        registry = Registry.load(plugins_named(job))
        cfg = OmegaConf.to_container(cfg, resolve=True)
        if cfg["data"]["component"] != "simulate":
            cfg["data"] = {"component": "simulate", "n_steps": 10, "heldout_steps": 0}
        try:
            parts = registry.build(cfg)
            make_learner(cfg, parts).check_params(n_gds=getattr(parts.env, "n_gds", 0))
        except ValueError as exc:
            failed.append((job, str(exc)))
    return failed


@pytest.mark.parametrize("command, comment, page",
                         [c for c in documented_commands() if " --" not in c[0]],
                         ids=[c[0] for c in documented_commands() if " --" not in c[0]])
def test_every_documented_command_composes_and_passes_the_early_checks(command, comment, page,
                                                                         make_cfg, tmp_path,
                                                                         monkeypatch):
    files = code_files()
    monkeypatch.chdir(tmp_path)           # plugins the pages define are written here
    for name, code in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(code)
    if command in INSTALLED_PLUGINS:
        command += f" 'plugins=[{INSTALLED_PLUGINS[command]}]'"
    if comment.startswith("rejected"):
        with pytest.raises(Exception) as refused:
            compose_checked(command, make_cfg)
        keys = [o.partition("=")[0] for o in overrides_of(shlex.split(command)[1:])]
        assert any(key in str(refused.value) for key in keys), (page, str(refused.value))
        return
    failed = compose_checked(command, make_cfg)
    assert len(failed) == DOCUMENTED_FAILURES.get(command, 0), (page, failed)


@pytest.mark.parametrize("command", [c for c in page_commands(DOCS / "configuration.md")
                                     if " --" not in c and "data.path=" not in c])
def test_configuration_examples_run(command, make_cfg, tmp_path):
    args = overrides_of(shlex.split(command)[1:])
    results = run(make_cfg([*args, *SHORT]), tmp_path)
    assert results["n_states"]["final"] >= results["n_states"]["phase1"]
    assert (tmp_path / "map.json").is_file()


@pytest.mark.slow
def test_first_sweep_example_runs_every_job(tmp_path):
    (command,) = [c for c in page_commands(DOCS / "sweeps.md") if " -m " in c][:1]
    args = shlex.split(command)[1:]
    proc = subprocess.run([sys.executable, "-m", "topomap", *args, *SHORT], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    (sweep,) = (tmp_path / "outputs" / "sweeps").glob("*/*")
    rows = (sweep / "summary.csv").read_text().splitlines()[1:]
    assert len(rows) == 9 and all(",completed," in r for r in rows), rows


@pytest.mark.slow
def test_cfg_resolve_prints_the_config_with_the_seed_filled_in(tmp_path):
    assert "topomap --cfg job --resolve" in page_commands(DOCS / "configuration.md")
    proc = subprocess.run([sys.executable, "-m", "topomap", "--cfg", "job", "--resolve", "seed=7"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "${" not in proc.stdout and "seed: 7" in proc.stdout
