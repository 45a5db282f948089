"""Loggers (``topomap logger=...``): MLflow keeps every run, read back with MLflow's own client,
and a plugin's logger is called the same way."""

import json
import textwrap

import pytest

from topomap.app.compose.command_line import compose
from topomap.app.run.experiment import run
from topomap.app.components.loggers import MLflowLogger, RunRecord
from topomap.app.compose.registry import Registry

SMALL = ["data.n_steps=300", "data.heldout_steps=200", "clusters.ns=8", "stop.n_states=12",
         "output.progress=false"]


@pytest.fixture(scope="module")
def client_of():
    pytest.importorskip("mlflow")
    from mlflow.tracking import MlflowClient

    return lambda uri: MlflowClient(tracking_uri=uri)


def test_mlflow_logs_config_metrics_series_and_files(tmp_path, monkeypatch, client_of):
    monkeypatch.chdir(tmp_path)  # the default store is outputs/ below the folder started from
    out = tmp_path / "outputs" / "runs" / "day" / "run0"
    results = run(compose([*SMALL, "logger=mlflow"]), out)
    client = client_of(f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("topomap")
    (logged,) = client.search_runs([experiment.experiment_id])
    assert logged.info.run_name == "day/run0" and logged.info.status == "FINISHED"
    assert logged.data.tags["topomap.output_dir"] == str(out.resolve())
    params = logged.data.params
    assert params["clusters.ns"] == "8" and params["data.n_steps"] == "300"
    assert params["logger.component"] == "mlflow" and params["objective"] == "heldout_loglik"
    metrics = json.loads((out / "metrics.json").read_text())
    logged_metrics = logged.data.metrics
    assert logged_metrics["ari"] == metrics["ground_truth"]["final"]["ari"]
    assert logged_metrics["purity_phase1"] == metrics["ground_truth"]["phase1"]["purity"]
    assert logged_metrics["heldout_loglik"] == results["heldout_loglik"]
    assert logged_metrics["n_states"] == 12 and logged_metrics["n_states_phase1"] == 10
    assert logged_metrics["H_x"] == metrics["entropies"]["final"]["H_x"]
    assert logged_metrics["time_phase1"] == metrics["timings"]["phase1"]
    history = client.get_metric_history(logged.info.run_id, "split.H_u")
    trace = metrics["entropy_trace"]
    assert [(h.step, h.value) for h in sorted(history, key=lambda h: h.step)] == \
        [(k, e["H_u"]) for k, e in enumerate(trace)]
    assert len(trace) == 3  # phase 1, then 2 splits (10 -> 12 states)
    files = {a.path for a in client.list_artifacts(logged.info.run_id)}
    assert {"map.json", "map.graphml", "metrics.json", "map.html", "fig_states.png",
            "fig_map.png", "fig_entropy.png"} <= files
    local = client.download_artifacts(logged.info.run_id, "map.json", str(tmp_path))
    assert open(local, "rb").read() == (out / "map.json").read_bytes()


def test_runs_share_the_named_experiment_and_store(tmp_path, client_of):
    uri = f"sqlite:///{tmp_path / 'store.db'}"
    for seed in (0, 1):
        run(compose([*SMALL, "output.figures=false", "logger=mlflow", f"seed={seed}",
                     f"logger.tracking_uri={uri}", "logger.experiment=two_seeds"]),
            tmp_path / f"run{seed}")
    assert (tmp_path / "mlartifacts").is_dir()  # beside the given store, not in the cwd
    client = client_of(uri)
    experiment = client.get_experiment_by_name("two_seeds")
    runs = client.search_runs([experiment.experiment_id])
    assert sorted(r.data.params["seed"] for r in runs) == ["0", "1"]
    assert client.get_experiment_by_name("topomap") is None
    for r in runs:  # without figures, the map and the metrics only
        assert {a.path for a in client.list_artifacts(r.info.run_id)} == \
            {"map.json", "map.graphml", "metrics.json"}


def test_bad_logger_settings_name_the_key(tmp_path):
    pytest.importorskip("mlflow")
    with pytest.raises(ValueError, match="logger=mlflow: logger.experiment must name"):
        run(compose([*SMALL, "logger=mlflow", "logger.experiment="]), tmp_path / "a")
    with pytest.raises(ValueError, match=r"unknown logger=nope; did you mean logger=none\?"):
        compose([*SMALL, "logger=nope"])
    assert not (tmp_path / "a").exists()


def test_default_store_is_below_the_outputs_folder(tmp_path):
    uri, artifacts = MLflowLogger().store(tmp_path)
    assert uri == f"sqlite:///{tmp_path.resolve() / 'outputs' / 'mlflow.db'}"
    assert artifacts == (tmp_path.resolve() / "outputs" / "mlartifacts").as_uri()
    assert MLflowLogger("http://tracking:5000").store(tmp_path) == ("http://tracking:5000", None)
    given = f"sqlite:///{tmp_path / 'elsewhere' / 'runs.db'}"
    assert MLflowLogger(given).store(tmp_path) == \
        (given, (tmp_path / "elsewhere" / "mlartifacts").as_uri())


PLUGIN = '''
    from topomap import Component, hookimpl

    RECORDS = []

    class Remember:
        """Keeps what it is given (a stand-in for W&B or TensorBoard)."""
        def __init__(self, project: str = "maps"):
            self.project = project

        def log_run(self, record):
            RECORDS.append((self.project, record))

    @hookimpl
    def topomap_register_components():
        return [Component("logger", "remember", Remember, description="keeps its records")]
'''


def test_a_plugin_adds_a_logger_through_the_components_hook(tmp_path):
    path = tmp_path / "remember_logger.py"
    path.write_text(textwrap.dedent(PLUGIN))
    registry = Registry.load([str(path)])
    cfg = compose([*SMALL, "output.figures=false", f"plugins=[{path}]", "logger=remember",
                   "logger.project=office"], registry)
    results = run(cfg, tmp_path / "out", registry=registry)
    ((project, record),) = registry.pm.get_plugin(str(path)).RECORDS
    assert project == "office" and isinstance(record, RunRecord)
    assert record.results is results and record.sweep_dir is None
    assert record.metrics()["ari"] == results["ground_truth"]["final"]["ari"]
    assert record.params()["logger.project"] == "office"
    assert [p.name for p in record.artifacts()] == ["map.json", "map.graphml", "metrics.json"]


def test_a_tracking_server_that_does_not_answer_is_refused_before_learning(tmp_path):
    """Nothing listens on the port: one line, within seconds, and no run folder."""
    import socket
    import time

    pytest.importorskip("mlflow")
    with socket.socket() as s:  # a port nothing listens on once closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=rf"^logger=mlflow: logger.tracking_uri=http://127.0.0.1:"
                                         rf"{port}: no MLflow tracking server answers"):
        run(compose([*SMALL, "logger=mlflow", f"logger.tracking_uri=http://127.0.0.1:{port}"]),
            tmp_path / "run")
    assert time.perf_counter() - t0 < 30 and not (tmp_path / "run").exists()


def test_the_jobs_of_a_sweep_are_children_of_the_sweeps_run(tmp_path, client_of):
    """Two jobs of one sweep: one parent run (the sweep), both jobs its children; the sweep's
    report files go to the parent, which then ends."""
    uri = f"sqlite:///{tmp_path / 'store.db'}"
    logger = MLflowLogger(tracking_uri=uri)
    sweep = tmp_path / "sweep"
    ids = []
    for job in ("0", "1"):
        (sweep / job).mkdir(parents=True)
        ids.append(logger.log_run(RunRecord(sweep / job, {"seed": 0}, {"versions": {}},
                                            start_dir=tmp_path, sweep_dir=sweep)))
    (sweep / "summary.csv").write_text("job,ari\n0,1.0\n")
    parent = logger.log_sweep(sweep, tmp_path)
    client = client_of(uri)
    assert {client.get_run(i).data.tags["mlflow.parentRunId"] for i in ids} == {parent}
    assert client.get_run(parent).info.status == "FINISHED"
    assert [a.path for a in client.list_artifacts(parent)] == ["summary.csv"]
    assert logger.log_sweep(tmp_path / "no sweep", tmp_path) is None
