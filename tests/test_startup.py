"""The command answers at once: what ``import topomap`` and the quick commands import, and the
configs kept between commands (:mod:`topomap.app.compose.schema_cache`)."""

import dataclasses
import json
import os
import subprocess
import sys

import pytest

HEAVY = ("sklearn", "numba", "scipy", "pandas")


def _imported(code: str, tmp_path, cache_dir=None) -> dict:
    """Run ``code`` in a fresh interpreter; the top-level packages it imported, and its output."""
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1",
               TOPOMAP_CACHE_DIR=str(cache_dir or tmp_path / "cache"))
    probe = ("import sys, io, contextlib\nout = io.StringIO()\n"
             "with contextlib.redirect_stdout(out):\n"
             + "".join(f"    {line}\n" for line in code.splitlines())
             + "print(sorted({m.split('.')[0] for m in sys.modules}))\n")
    r = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return set(json.loads(r.stdout.strip().splitlines()[-1].replace("'", '"')))


def _command(args) -> str:
    return ("import sys\nsys.argv = ['topomap', " + ", ".join(repr(a) for a in args) + "]\n"
            "from topomap.app.cli import main\ntry:\n    main()\nexcept SystemExit:\n    pass")


def test_import_topomap_loads_the_core_alone(tmp_path):
    """No Hydra, pluggy or OmegaConf (the app), and not even scikit-learn or numba until a
    public name is used."""
    mods = _imported("import topomap", tmp_path)
    assert not mods & {"hydra", "pluggy", "omegaconf", *HEAVY}, mods
    mods = _imported("import topomap\ntopomap.MapLearner", tmp_path)
    assert {"sklearn", "numba"} <= mods and not mods & {"hydra", "pluggy", "omegaconf"}, mods


@pytest.mark.slow
def test_version_imports_no_heavy_library(tmp_path):
    mods = _imported(_command(["--version"]), tmp_path)
    assert not mods & {*HEAVY, "hydra", "omegaconf"}, mods


@pytest.mark.slow
@pytest.mark.parametrize("args", [["--help"], ["--cfg", "job"], ["clusters.ns=abc"]])
def test_help_and_the_config_load_no_numba_nor_scikit_learn(args, tmp_path):
    """Once the configs are kept (the first command of an installation derives them)."""
    _imported(_command(args), tmp_path)  # keeps the derived configs
    mods = _imported(_command(args), tmp_path)
    assert not mods & set(HEAVY), mods


def test_a_kept_config_equals_the_derived_one(tmp_path, monkeypatch):
    """Every built-in component's config read back from the cache file is the one its
    signature gives: same fields, types and defaults, and the same keys of before a rename."""
    from topomap.app.compose import schema_cache
    from topomap.app.compose.registry import Registry
    from topomap.app.compose.schemas import fields_of, learner_schema, schema_of

    def fresh():
        monkeypatch.setattr(schema_cache, "_memo", {})
        monkeypatch.setattr(schema_cache, "_stored", None)

    monkeypatch.setenv(schema_cache.CACHE_ENV, str(tmp_path))
    registry = Registry.load(entry_points_group=None)
    fresh()
    derived = {(k, n): schema_of(c) for k, n, c, _ in registry.items()}
    derived["learner"] = learner_schema()
    assert schema_cache.cache_file().is_file()
    fresh()
    kept = {(k, n): schema_of(c) for k, n, c, _ in registry.items()}
    kept["learner"] = learner_schema()
    assert kept.keys() == derived.keys()
    for key in derived:
        a, b = derived[key], kept[key]
        assert a.__name__ == b.__name__
        assert [(f.name, str(f.type)) for f in dataclasses.fields(a)] == \
               [(f.name, str(f.type)) for f in dataclasses.fields(b)], key
        assert repr(fields_of(a)) == repr(fields_of(b)), key
        assert schema_cache.renamed_of(a) == schema_cache.renamed_of(b), key
    assert schema_cache.renamed_of(kept[("refine", "em")])["max_iter"] == "hard.max_iter"


def test_a_changed_source_file_is_a_new_cache_key(tmp_path, monkeypatch):
    from topomap.app.compose import schema_cache

    package = tmp_path / "package"
    (package / "sub").mkdir(parents=True)
    source = package / "sub" / "a.py"
    source.write_text("x = 1\n")
    (package / "notes.txt").write_text("not a source file")
    before = schema_cache.source_stamp(package)
    (package / "notes.txt").write_text("still not one")
    assert schema_cache.source_stamp(package) == before
    source.write_text("x = 22\n")
    assert schema_cache.source_stamp(package) != before
    monkeypatch.setenv(schema_cache.CACHE_ENV, "")
    assert schema_cache.cache_file() is None


def test_a_lazy_name_is_imported_on_first_use_and_kept(monkeypatch):
    """A package's public name comes from its module when first asked for, then from the
    package itself; any other name is an AttributeError naming the package."""
    import types

    from topomap.core.lazy import lazy_getattr

    package = types.ModuleType("lazypkg")
    package.__path__ = []
    inner = types.ModuleType("lazypkg.inner")
    inner.VALUE = object()
    monkeypatch.setitem(sys.modules, "lazypkg", package)
    monkeypatch.setitem(sys.modules, "lazypkg.inner", inner)
    package.__getattr__ = lazy_getattr("lazypkg", {"VALUE": ".inner"})
    assert "VALUE" not in vars(package)
    assert package.VALUE is inner.VALUE
    assert vars(package)["VALUE"] is inner.VALUE
    with pytest.raises(AttributeError, match="'lazypkg' has no attribute 'OTHER'"):
        package.OTHER


@pytest.mark.parametrize("name", ["topomap", "topomap.core", "topomap.worlds"])
def test_dir_lists_a_packages_public_names_before_they_are_imported(name, tmp_path):
    """``dir()`` of a package (what an editor completes) lists every public name, in a fresh
    interpreter where none of them has been imported yet."""
    code = (f"import importlib, sys; p = importlib.import_module({name!r}); "
            "missing = sorted(set(p.__all__) - set(dir(p))); "
            "print(missing, 'sklearn' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120, check=True).stdout
    assert out.strip() == "[] False"


@pytest.mark.slow
def test_a_kept_help_is_the_composed_one_and_imports_no_hydra(tmp_path):
    """The second bare ``--help`` prints the first one's text from the kept file, without Hydra
    or OmegaConf; with an override the help is composed again."""
    env = dict(os.environ, TOPOMAP_DISABLE_PLUGIN_AUTOLOAD="1", TOPOMAP_CACHE_DIR=str(tmp_path))

    def run(*args):
        r = subprocess.run([sys.executable, "-m", "topomap", *args], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        return r.stdout

    composed = run("--help")
    assert composed.startswith("topomap: learn a robot") and "\nseed: 0\n" in composed
    assert len(list(tmp_path.glob("help-*.txt"))) == 1
    assert run("--help") == composed
    mods = _imported(_command(["--help"]), tmp_path, cache_dir=tmp_path)
    assert not mods & {"hydra", "omegaconf", *HEAVY}, mods
    assert "\nseed: 7\n" in run("--help", "seed=7")
    assert len(list(tmp_path.glob("help-*.txt"))) == 1


def test_the_kept_help_s_key_follows_the_plugins_and_their_autoload(tmp_path, monkeypatch):
    import importlib.metadata as md

    from topomap.app.compose import help_cache, schema_cache

    monkeypatch.setenv(schema_cache.CACHE_ENV, str(tmp_path))
    monkeypatch.delenv("TOPOMAP_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    base = help_cache.help_file()
    assert base.parent == tmp_path and base == help_cache.help_file()
    monkeypatch.setenv("TOPOMAP_DISABLE_PLUGIN_AUTOLOAD", "1")
    assert help_cache.help_file() != base
    monkeypatch.delenv("TOPOMAP_DISABLE_PLUGIN_AUTOLOAD")
    added = md.EntryPoint("mine", "json:dumps", "topomap")
    monkeypatch.setattr(md, "entry_points", lambda group: [added] if group == "topomap" else [])
    assert help_cache.help_file() != base
    monkeypatch.setenv(schema_cache.CACHE_ENV, "")
    assert help_cache.help_file() is None and help_cache.kept_help(["--help"]) is None


def test_only_a_help_that_ends_well_is_kept(tmp_path, monkeypatch, capsys):
    from topomap.app.compose import help_cache, schema_cache

    monkeypatch.setenv(schema_cache.CACHE_ENV, str(tmp_path))
    with pytest.raises(SystemExit):
        with help_cache.keeping_help(["--help"]):
            print("half a help")
            raise SystemExit(2)
    assert help_cache.kept_help(["--help"]) is None
    with help_cache.keeping_help(["--help", "seed=3"]):
        print("help of an override")
    assert help_cache.kept_help(["--help", "seed=3"]) is None
    with pytest.raises(SystemExit):
        with help_cache.keeping_help(["-h"]):
            print("the whole help")
            raise SystemExit(0)
    assert help_cache.kept_help(["--help"]) == "the whole help\n"
    assert "half a help" in capsys.readouterr().out
