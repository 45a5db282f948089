"""The one private Hydra API topomap uses, held to what topomap relies on: this test fails, naming
what changed, when a Hydra release changes it.

``topomap.app.compose.command_line.hydra_arguments`` reads the command line with
``hydra._internal.utils.get_args_parser`` (Hydra has no public parser); the sweep report knows
Hydra's grid sweeper by its option, ``hydra/sweeper=basic``, in the config's public
``hydra.runtime.choices``.
"""

import argparse

from topomap.app.compose.command_line import NOT_A_RUN, hydra_arguments, overrides_of
from topomap.app.report.jobs import BASIC_SWEEPER


def test_hydras_own_parser_is_there():
    from hydra._internal.utils import get_args_parser

    assert isinstance(get_args_parser(), argparse.ArgumentParser)


def test_hydras_parser_reads_overrides_and_the_multirun_flag():
    args = hydra_arguments(["-m", "clusters.ns=10,20", "seed=1"])
    assert args.multirun is True and args.overrides == ["clusters.ns=10,20", "seed=1"]
    args = hydra_arguments(["seed=1"])
    assert not args.multirun and overrides_of(["seed=1", "--multirun"]) == ["seed=1"]


def test_every_flag_that_does_not_run_is_known_to_hydras_parser():
    """Each flag of NOT_A_RUN is an attribute of the parsed command line, unset by default; the
    ones that take a value take it."""
    plain = hydra_arguments(["seed=1"])
    for flag in NOT_A_RUN:
        assert hasattr(plain, flag), f"Hydra's parser has no {flag!r} any more"
        assert not getattr(plain, flag), flag
    assert hydra_arguments(["--cfg", "job", "seed=1"]).cfg == "job"
    assert hydra_arguments(["--help"]).help is True
    assert hydra_arguments(["--hydra-help"]).hydra_help is True
    assert hydra_arguments(["--info", "config"]).info == "config"


def test_a_grid_is_known_by_its_sweeper_option(make_cfg):
    cfg = make_cfg(hydra=True)
    assert cfg.hydra.runtime.choices["hydra/sweeper"] == BASIC_SWEEPER
    assert cfg.hydra.sweeper._target_.endswith(".BasicSweeper")
