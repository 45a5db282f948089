"""Shared test set-up: no installed plugin is loaded unless a test asks for it, and one fixture
composes the app's config."""

import os
import pathlib
import sys

import pytest

# installed plugins (entry points) must not change what the tests see; tests that need them
# unset this for their subprocess
os.environ["TOPOMAP_DISABLE_PLUGIN_AUTOLOAD"] = "1"
sys.path.insert(0, str(pathlib.Path(__file__).parent))


@pytest.fixture
def make_cfg():
    """``make_cfg(overrides=(), hydra=False)``: the config ``topomap <overrides>`` composes."""
    from topomap.app.compose.command_line import compose

    def make(overrides=(), hydra=False):
        return compose(overrides, return_hydra_config=hydra)

    return make
