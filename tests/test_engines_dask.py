"""The Dask engine on a real ``distributed.LocalCluster`` (worker processes on 127.0.0.1).

The cluster runs give the in-process results exactly: the tasks are the same pure
functions on the same inputs, and OpenCV's USAC is seeded the same way on every
call, whichever process runs it.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

if os.environ.get("CI") is None:
    pytest.importorskip("distributed", reason="the 'distributed' extra is not installed")

import dask  # noqa: E402
import distributed  # noqa: E402

from scene3D.cli import main as scene3d_main  # noqa: E402
from scene3D.cli.evaluate import main as evaluate_main  # noqa: E402
from scene3D.cli.multiview import main as views_main  # noqa: E402
from scene3D.engines import LocalEngine  # noqa: E402
from scene3D.engines.dask_engine import DaskEngine  # noqa: E402
from scene3D.errors import EngineError, ReconstructionError  # noqa: E402
from scene3D.evaluation.pairs import evaluate_pairs  # noqa: E402
from scene3D.io.datasets import read_strecha_camera, strecha_views  # noqa: E402
from scene3D.multiview import reconstruct_views  # noqa: E402
from scene3D.twoview import TwoViewSettings  # noqa: E402

# A few small pairs of fountain-P11 at the book's 768 px: quick, and enough for two workers.
PAIRS = [(0, 1), (1, 2), (2, 3), (0, 2)]
MAX_WIDTH = 1200


def _cluster() -> distributed.LocalCluster:
    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                    host="127.0.0.1", dashboard_address=":0")


@pytest.fixture(scope="module")
def client():
    with _cluster() as cluster, distributed.Client(cluster, set_as_default=False) as client:
        yield client


@pytest.fixture(scope="module")
def fountain_views(fountain):
    views = strecha_views(fountain)[:6]
    return [image for image, _ in views], [read_strecha_camera(c) for _, c in views]


@pytest.fixture(scope="module")
def local_rows(fountain_views):
    return list(evaluate_pairs(LocalEngine(), *fountain_views, PAIRS, MAX_WIDTH, "SIFT",
                               TwoViewSettings()))


def _without_seconds(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]


# Task functions: module-level, so that the workers import them by name.

def _power(base: int, exponent: int) -> int:
    return base**exponent


def _seen_by_worker(path: Path) -> tuple[str, str, str]:
    """What the task was given: its path, the SHA-256 of the content, the worker."""
    return str(path), hashlib.sha256(Path(path).read_bytes()).hexdigest(), \
        distributed.get_worker().address


def _refuse(count: int) -> None:
    raise ReconstructionError("too_few_matches", "too few matches", matches=count)


def _die() -> None:
    os._exit(3)  # the worker process ends, as when it is killed


def _pause(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def _squares(n: int) -> np.ndarray:
    return np.arange(n) ** 2


def _sum_of(values: np.ndarray | list[int], extra: int) -> int:
    return int(np.sum(values)) + extra


# -- the engine -------------------------------------------------------------------------

def test_map_runs_on_the_workers_in_order_with_progress(client):
    engine = DaskEngine(client)
    seen = []
    results = list(engine.map(_power, [(2, k) for k in range(12)], label="powers",
                              progress=lambda *report: seen.append(report)))
    assert results == [2**k for k in range(12)]
    # One report per finished task, counted up to the total (tasks finish in any order).
    assert seen == [("powers", done, 12) for done in range(1, 13)]
    counts = engine.task_counts()
    assert set(counts) == set(engine.workers()) and len(counts) == 2
    assert sum(c.get("powers", 0) for c in counts.values()) == 12 == engine.submitted["powers"]


def test_share_hands_on_the_task_that_made_a_result(client):
    engine = DaskEngine(client)
    (made,) = engine.map(_squares, [(4,)])
    handle = engine.share(made)
    assert isinstance(handle, distributed.Future) and handle.key.startswith("tasks-")
    assert list(engine.map(_sum_of, [(handle, 1)])) == [1 + 4 + 9 + 1]
    # A value from elsewhere (or a result that cannot be tracked, such as an int) is sent
    # once, as a task that returns it (a list as one value, not item by item).
    values = list(range(1000))
    sent = engine.share(values)
    assert isinstance(sent, distributed.Future) and sent.key.startswith("shared-")
    assert list(engine.map(_sum_of, [(sent, 1)])) == [sum(values) + 1]


def test_a_task_error_is_raised_with_its_type_and_details(client):
    engine = DaskEngine(client)
    with pytest.raises(ReconstructionError) as info:
        list(engine.map(_refuse, [(3,)]))
    assert info.value.reason == "too_few_matches" and info.value.counts == {"matches": 3}


def test_a_file_a_worker_cannot_read_names_the_file_and_the_worker(client, tmp_path):
    engine = DaskEngine(client, files="shared")
    missing = tmp_path / "gone" / "0007.jpg"
    from scene3D.io.images import read_image

    with pytest.raises(FileNotFoundError) as info:
        list(engine.map(read_image, [(missing,)]))
    message = str(info.value)
    assert str(missing) in message
    worker = message.rsplit("(on worker ", 1)[1].rstrip(")")
    assert worker in engine.workers()


def test_files_go_as_paths_when_the_workers_see_them_else_as_bytes(client, fountain):
    image = fountain / "images" / "0004.jpg"
    digest = hashlib.sha256(image.read_bytes()).hexdigest()
    relative = Path(os.path.relpath(image))  # the workers' working folder is not ours
    shared = DaskEngine(client)  # auto: the workers are on this machine
    (path, seen, _), = shared.map(_seen_by_worker, [(relative,)])
    assert Path(path).is_absolute() and Path(path).resolve() == image.resolve()
    assert seen == digest
    sent = DaskEngine(client, files="send")  # as for workers that cannot see the file
    (path, seen, _), = sent.map(_seen_by_worker, [(image,)])
    assert path != str(image) and Path(path).name == image.name and seen == digest
    assert not Path(path).exists()  # the worker's copy is gone with the task


# -- evaluate on the cluster ------------------------------------------------------------

@pytest.mark.parametrize("files", ["auto", "send"])
def test_evaluate_on_the_cluster_gives_the_local_rows(client, fountain_views, local_rows,
                                                     files):
    engine = DaskEngine(client, files=files)
    rows = list(evaluate_pairs(engine, *fountain_views, PAIRS, MAX_WIDTH, "SIFT",
                               TwoViewSettings()))
    assert [r["pair"] for r in rows] == [r["pair"] for r in local_rows]
    # Exactly: every error, inlier count, focal fit and note (NaN equal to NaN).
    np.testing.assert_equal(_without_seconds(rows), _without_seconds(local_rows))
    assert all(r["rotation_deg"] < 1.0 for r in rows)
    counts = engine.task_counts()
    assert sum(c.get("views", 0) for c in counts.values()) == 4  # views 0-3, once each
    assert sum(c.get("pairs", 0) for c in counts.values()) == len(PAIRS)


def test_evaluate_no_calib_on_the_cluster_gives_the_local_rows(client, fountain_views):
    args = (fountain_views[0], fountain_views[1], PAIRS[:2], MAX_WIDTH, "SIFT",
            TwoViewSettings())
    local = list(evaluate_pairs(LocalEngine(), *args, no_calib=True))
    rows = list(evaluate_pairs(DaskEngine(client), *args, no_calib=True))
    np.testing.assert_equal(_without_seconds(rows), _without_seconds(local))
    assert [r["calibration_source"] for r in rows] == ["prior+refined"] * 2


def test_a_worker_killed_mid_run_does_not_lose_the_run(fountain_views, local_rows):
    pairs = PAIRS + [(3, 4), (4, 5), (1, 3), (2, 4)]  # enough to keep both workers busy
    expected = _without_seconds(local_rows) + _without_seconds(
        list(evaluate_pairs(LocalEngine(), *fountain_views, pairs[len(PAIRS):], MAX_WIDTH,
                            "SIFT", TwoViewSettings())))
    with _cluster() as cluster, distributed.Client(cluster, set_as_default=False) as client:
        engine = DaskEngine(client)
        pids = client.run(os.getpid)
        killed: list[str] = []

        def kill_a_busy_worker(label: str, done: int, total: int) -> None:
            if label == "pairs" and not killed:  # the first pair is done, the rest running
                busy = [w for w, keys in client.processing().items() if keys]
                assert busy, "no task was running when the worker was to be killed"
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])

        rows = list(evaluate_pairs(engine, *fountain_views, pairs, MAX_WIDTH, "SIFT",
                                   TwoViewSettings(), kill_a_busy_worker))
        np.testing.assert_equal(_without_seconds(rows), expected)
        # The worker really died with tasks on it, and the scheduler ran them again
        # (its nanny starts a new worker process, under a new address).
        assert killed and killed[0] not in engine.workers()
        assert cluster.scheduler.task_prefixes["pairs"].suspicious >= 1
        # What -v reports: the tasks the dead worker finished went with its counts.
        counted = sum(sum(c.values()) for c in engine.task_counts().values())
        assert counted <= engine.submitted.total() == 6 + len(pairs)


def test_a_task_whose_workers_keep_dying_is_given_up_with_an_engine_error():
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=":0") as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        with pytest.raises(EngineError, match="tasks task 0 was given up: the worker running "
                                              "it died 1 time "):
            list(DaskEngine(client).map(_die, [()]))


def test_a_run_whose_workers_all_left_stops_with_an_engine_error():
    """Dask reschedules the tasks of workers that leave and waits for another, without
    limit: the engine stops the wait once the cluster has had no worker for its limit.
    The first task has finished, but its value left with its worker before it was
    fetched (the fetch waited without limit until 2026-12-03)."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0") as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        engine = DaskEngine(client, no_worker_timeout_s=2.0)

        def remove_the_workers(label: str, done: int, total: int) -> None:
            if done == 1:
                cluster.scale(0)
                deadline = time.monotonic() + 20
                while client.nthreads() and time.monotonic() < deadline:
                    time.sleep(0.05)

        started = time.monotonic()
        with pytest.raises(EngineError, match=r"^the Dask cluster has had no worker for 2 s "
                                              r"while pauses tasks waited"):
            list(engine.map(_pause, [(0.0,)] + [(1.0,)] * 4, label="pauses",
                            progress=remove_the_workers))
        assert time.monotonic() - started < 30


def test_a_worker_or_a_tls_address_is_refused_in_one_line(client):
    worker = next(iter(client.scheduler_info()["workers"]))
    with pytest.raises(OSError, match=r"is a Dask worker, not the scheduler: give the address "
                                      r"'dask scheduler' prints"):
        DaskEngine.connect(worker)
    with pytest.raises(ValueError, match=r"needs TLS, and Dask's configuration holds no "
                                         r"certificates"):
        DaskEngine.connect(client.scheduler.address.replace("tcp://", "tls://"))


def test_workers_of_another_scene3d_version_are_refused_at_connect(client, monkeypatch):
    import scene3D

    with DaskEngine.connect(client.scheduler.address) as engine:  # the same version
        assert len(engine.workers()) == 2
    monkeypatch.setattr(scene3D, "__version__", "9.9.9")
    with pytest.raises(OSError, match=r"^worker tcp://127.0.0.1:\d+ runs scene3D 0.1.0 and "
                                      r"this client 9.9.9 \(1 more alike\): install one "
                                      r"version everywhere"):
        DaskEngine.connect(client.scheduler.address)


# -- reconstruct-views on the cluster -------------------------------------------------

VIEWS = 6  # the first fountain-P11 images, all 15 pairs, at 768 px


@pytest.fixture(scope="module")
def local_model(fountain_views):
    images, cameras = fountain_views
    return reconstruct_views(images[:VIEWS], cameras[0].K, np.zeros(5), max_width=MAX_WIDTH,
                             engine=LocalEngine())


def _same_cameras(recon, reference) -> None:
    """The same views registered, with the same cameras, exactly."""
    assert recon.names == reference.names and recon.registered.all()
    np.testing.assert_array_equal(recon.registered, reference.registered)
    np.testing.assert_array_equal(recon.R, reference.R)
    np.testing.assert_array_equal(recon.t, reference.t)
    np.testing.assert_array_equal(recon.points3d, reference.points3d)


class _KillAtFirstPair:
    """An engine that kills a worker running tasks when the first pair is verified."""

    def __init__(self, engine: DaskEngine) -> None:
        self.engine, self.name = engine, engine.name
        self.pids = engine.client.run(os.getpid)
        self.killed: list[str] = []

    def _progress(self, label: str, done: int, total: int) -> None:
        if label == "pairs" and not self.killed:
            busy = [w for w, keys in self.engine.client.processing().items() if keys]
            assert busy, "no task was running when the worker was to be killed"
            os.kill(self.pids[busy[0]], signal.SIGKILL)
            self.killed.append(busy[0])

    def map(self, fn, arguments, *, label="tasks", progress=None):
        return self.engine.map(fn, arguments, label=label, progress=self._progress)

    def share(self, value):
        return self.engine.share(value)


def test_reconstruct_views_on_the_cluster_gives_the_local_cameras(client, fountain_views,
                                                                   local_model):
    images, cameras = fountain_views
    engine = DaskEngine(client)
    recon = reconstruct_views(images[:VIEWS], cameras[0].K, np.zeros(5), max_width=MAX_WIDTH,
                              engine=engine)
    _same_cameras(recon, local_model)
    counts = engine.task_counts()
    assert sum(c.get("features", 0) for c in counts.values()) == VIEWS
    assert sum(c.get("pairs", 0) for c in counts.values()) == VIEWS * (VIEWS - 1) // 2
    assert all(c.get("pairs", 0) > 0 for c in counts.values())  # both workers matched


def test_a_worker_killed_during_reconstruct_views_does_not_lose_the_run(fountain_views,
                                                                        local_model):
    images, cameras = fountain_views
    with _cluster() as cluster, distributed.Client(cluster, set_as_default=False) as client:
        engine = _KillAtFirstPair(DaskEngine(client))
        recon = reconstruct_views(images[:VIEWS], cameras[0].K, np.zeros(5),
                                  max_width=MAX_WIDTH, engine=engine)
        _same_cameras(recon, local_model)
        assert engine.killed and engine.killed[0] not in engine.engine.workers()
        assert cluster.scheduler.task_prefixes["pairs"].suspicious >= 1


def test_reconstruct_views_command_with_scheduler(client, fountain_views,
                                                  local_model, tmp_path, capsys):
    images, _ = fountain_views
    for image in images[:VIEWS]:
        (tmp_path / image.name).symlink_to(image)
    calib = Path(__file__).resolve().parents[1] / "data" / "fountain_P11_intrinsics.yaml"
    code = views_main([str(tmp_path), "--calib", str(calib), "--max-width", str(MAX_WIDTH),
                       "--no-plots", "--no-report", "--out", str(tmp_path / "out"),
                       "--scheduler", client.scheduler.address, "-v", "--progress"])
    err = capsys.readouterr().err
    assert code == 0, err
    cameras = json.loads((tmp_path / "out" / "cameras.json").read_text())
    assert sorted(cameras) == sorted(local_model.names)
    for v, name in enumerate(local_model.names):
        np.testing.assert_array_equal(cameras[name]["R"], local_model.R[v])
        np.testing.assert_array_equal(cameras[name]["t"], local_model.t[v])
    assert f"tasks on dask {client.scheduler.address}: 2 workers" in err
    assert f"features: {VIEWS} of {VIEWS} done" in err and "pairs: 15 of 15 done" in err
    assert len([line for line in err.splitlines() if line.startswith("INFO: worker tcp://")]) == 2


# -- the command ------------------------------------------------------------------------

def _csv_rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k != "seconds"} for row in csv.DictReader(f)]


def test_evaluate_command_with_scheduler_gives_the_local_table(client, fountain, tmp_path,
                                                              capsys):
    address = client.scheduler.address
    args = [str(fountain), "--pairs", "4-5", "2-4"]
    assert evaluate_main([*args, "--csv", str(tmp_path / "local.csv")]) == 0
    capsys.readouterr()
    assert evaluate_main([*args, "--csv", str(tmp_path / "cluster.csv"), "--scheduler",
                          address, "-v", "--progress"]) == 0  # stderr is a capture
    err = capsys.readouterr().err
    assert _csv_rows(tmp_path / "cluster.csv") == _csv_rows(tmp_path / "local.csv")
    assert f"tasks on dask {address}: 2 workers, 2 threads" in err
    assert "views: 3 of 3 done" in err and "pairs: 2 of 2 done" in err
    ran = [line for line in err.splitlines() if line.startswith("INFO: worker tcp://")]
    assert len(ran) == 2  # -v: what each worker ran


def test_evaluate_command_names_the_file_a_worker_cannot_read(client, fountain, tmp_path,
                                                              capsys):
    for sub in ("images", "gt_dense_cameras"):
        (tmp_path / sub).mkdir()
    for name in ("0004.jpg", "0005.jpg"):
        (tmp_path / "gt_dense_cameras" / f"{name}.camera").symlink_to(
            fountain / "gt_dense_cameras" / f"{name}.camera")
    (tmp_path / "images" / "0004.jpg").symlink_to(fountain / "images" / "0004.jpg")
    (tmp_path / "images" / "0005.jpg").symlink_to(tmp_path / "nowhere.jpg")  # dangling
    code = evaluate_main([str(tmp_path), "--scheduler", client.scheduler.address, "-q"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert str(tmp_path / "images" / "0005.jpg") in err and "(on worker tcp://127.0.0.1:" in err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("argv, message", [
    (["--scheduler", "tcp://127.0.0.1:{port}"], "cannot connect to the Dask scheduler at"),
    (["--scheduler", "nonsense"], "bad Dask scheduler address 'nonsense'"),
    (["--scheduler", "tcp://127.0.0.1:99999"], "port 99999 is not between 1 and 65535"),
    (["--workers", "0"], "must be at least 1"),
    (["--workers", "100000"], "local workers beyond"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:{port}"], "not allowed with"),
])
def test_evaluate_command_bad_engine_options(fountain, capsys, argv, message):
    argv = [a.format(port=_free_port()) for a in argv]
    code = scene3d_main(["evaluate", str(fountain), "--pairs", "4-5", *argv])
    err = capsys.readouterr().err
    assert code == 2 and message in err
    assert "Traceback" not in err


def test_a_server_that_is_no_scheduler_is_refused_in_time():
    """The dashboard's port given for the scheduler's: a server that sends nothing (or no
    Dask handshake) is named as such, not waited on or misread."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        with pytest.raises(OSError, match="does not answer as a Dask scheduler"):
            DaskEngine.connect(address, timeout_s=0.5)


@pytest.mark.parametrize("command, option", [
    ("evaluate", ["--workers", "2"]),
    ("evaluate", ["--scheduler", "tcp://127.0.0.1:1"]),
    ("reconstruct-views", ["--workers", "2"]),
])
def test_without_the_extra_the_options_say_how_to_install_it(fountain, tmp_path, command,
                                                             option):
    # Dask missing: an import of distributed fails, as in a core install.
    calib = Path(__file__).resolve().parents[1] / "data" / "fountain_P11_intrinsics.yaml"
    inputs = ([str(fountain), "--pairs", "4-5"] if command == "evaluate" else
              [str(fountain / "images"), "--calib", str(calib), "--no-report", "--out",
               str(tmp_path / "out")])
    code = ("import sys; sys.modules['distributed'] = None\n"
            "from scene3D.cli import main\n"
            f"sys.exit(main([{command!r}, *{inputs!r}, *{option!r}]))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (f"error: {option[0]} needs Dask: pip install "
                                   "'scene3D[distributed]' (dask.distributed)")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
