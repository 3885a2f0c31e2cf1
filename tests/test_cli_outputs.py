"""The --out folder of reconstruct and reconstruct-views (scene3D.cli.outputs): a run
records its files, removes the previous run's it did not write again and nothing else,
refuses a reconstruction.json it did not write and any other file it would replace that is
not an earlier run's (or is one of its inputs), and a failed run leaves no empty folder."""

import json

import pytest

from scene3D.cli.common import EXIT_FAILED, EXIT_OK, UsageError, run_command
from scene3D.cli.outputs import (
    OutputFolder,
    prepare_output_dir,
    previous_outputs,
    recorded_files,
    remove_stale_outputs,
)


def _summary(out, files):
    (out / "reconstruction.json").write_text(json.dumps({"conventions": "x", "files": files}))


def test_stale_files_of_the_previous_run_go_and_nothing_else(tmp_path):
    out = tmp_path / "out"
    (out / "model-2" / "colmap").mkdir(parents=True)
    names = ["reconstruction.json", "report.html", "points.ply", "model-2/points.ply",
             "model-2/colmap/images.txt"]
    for name in names[1:]:
        (out / name).write_text("old")
    (out / "notes.txt").write_text("the user's")
    (tmp_path / "outside.txt").write_text("the user's")
    _summary(out, names + ["../outside.txt", "/etc/hostname", ""])
    previous = previous_outputs(out)
    assert recorded_files(out, previous) == sorted(names)
    written = [out / "reconstruction.json", out / "points.ply"]
    remove_stale_outputs(out, previous, written)
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert left == ["notes.txt", "points.ply", "reconstruction.json"]
    assert (tmp_path / "outside.txt").exists()


def test_a_recorded_file_behind_a_link_or_another_name_of_a_written_file_stays(tmp_path):
    """Hand-edited entries: one through a link inside the folder, one naming a file this
    run wrote under another name (a hard link here; a case-insensitive disk's REPORT.HTML
    is the same)."""
    out = tmp_path / "out"
    (out / "inner").mkdir(parents=True)
    (out / "inner" / "k.txt").write_text("the user's")
    (out / "linkin").symlink_to(out / "inner")
    (out / "report.html").write_text("this run's")
    (out / "alias.html").hardlink_to(out / "report.html")
    _summary(out, ["linkin/k.txt", "alias.html", "reconstruction.json"])
    removed = remove_stale_outputs(out, previous_outputs(out),
                                   [out / "reconstruction.json", out / "report.html"])
    assert removed == []
    assert (out / "inner" / "k.txt").exists() and (out / "alias.html").exists()


def test_a_recorded_file_behind_a_link_out_of_the_folder_stays(tmp_path):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (elsewhere / "points.ply").write_text("the user's")
    (out / "model-1").symlink_to(elsewhere)
    _summary(out, ["reconstruction.json", "model-1/points.ply"])
    remove_stale_outputs(out, previous_outputs(out), [out / "reconstruction.json"])
    assert (elsewhere / "points.ply").read_text() == "the user's"


@pytest.mark.parametrize("content", ['{"status": "mine"}', "not json", "[1, 2]"])
def test_a_reconstruction_json_scene3d_did_not_write_is_refused(tmp_path, content):
    (tmp_path / "reconstruction.json").write_text(content)
    with pytest.raises(UsageError, match="not written by scene3D"):
        previous_outputs(tmp_path)


def test_a_summary_from_before_the_file_list_removes_nothing(tmp_path):
    (tmp_path / "reconstruction.json").write_text('{"conventions": "x"}')
    assert previous_outputs(tmp_path) == []


def test_a_failed_run_removes_the_folders_it_created_if_empty(tmp_path):
    class Args:
        debug = False
        verbose = 0
        quiet = True

    def fails(args):
        prepare_output_dir(tmp_path / "a" / "b")
        return EXIT_FAILED

    def writes_then_fails(args):
        out = prepare_output_dir(tmp_path / "c")
        (out / "kept.txt").write_text("x")
        raise UsageError("bad")

    def succeeds(args):
        prepare_output_dir(tmp_path / "d")
        return EXIT_OK

    assert run_command(Args(), fails) == EXIT_FAILED
    assert not (tmp_path / "a").exists()
    assert run_command(Args(), writes_then_fails) == 2
    assert (tmp_path / "c" / "kept.txt").exists()
    assert run_command(Args(), succeeds) == EXIT_OK
    assert (tmp_path / "d").is_dir()

    # Only what this run made goes: "new/../old" makes "new", not "old".
    (tmp_path / "old").mkdir()

    def via_dotdot(args):
        prepare_output_dir(tmp_path / "new" / ".." / "old")
        return EXIT_FAILED

    assert run_command(Args(), via_dotdot) == EXIT_FAILED
    assert (tmp_path / "old").is_dir() and not (tmp_path / "new").exists()

    def crashes(args):  # an exception no handler expects still cleans up, then shows
        prepare_output_dir(tmp_path / "e")
        raise RuntimeError("a bug")

    with pytest.raises(RuntimeError):
        run_command(Args(), crashes)
    assert not (tmp_path / "e").exists()


def test_a_file_the_run_would_replace_must_be_an_earlier_runs(tmp_path):
    """A user's point_cloud.ply in --out, or one of the run's photos there (named like a
    figure), is refused; the earlier run's own files are replaced as before."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "point_cloud.ply").write_text("the user's")
    (out / "rectified.png").write_text("a photo")
    (out / "report.html").write_text("an earlier run's")
    _summary(out, ["report.html", "reconstruction.json"])
    folder = OutputFolder(out, inputs=[out / "rectified.png", tmp_path / "b.png"])
    folder.check_free([out / "report.html", out / "reconstruction.json", out / "new.ply"])
    with pytest.raises(UsageError, match=r"holds '.*point_cloud.ply', which no earlier "
                                         r"scene3D run there wrote"):
        folder.check_free([out / "report.html", out / "point_cloud.ply"])
    with pytest.raises(UsageError, match=r"would write '.*rectified.png', one of its inputs"):
        folder.record([out / "rectified.png"])
    # Without an earlier run, any file there is the user's.
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    (fresh / "report.html").write_text("the user's")
    with pytest.raises(UsageError, match="which no earlier"):
        OutputFolder(fresh).check_free([fresh / "report.html"])


def test_a_summary_from_before_the_file_list_owns_the_output_names(tmp_path):
    """Its run's files were not listed: the files named like the command's outputs are
    taken to be its (replaced, or removed when not written again, so that the next run's
    list holds them no more), but an input is still never written over."""
    (tmp_path / "model-1").mkdir()
    for name in ("point_cloud.ply", "optic_flow.png", "model-1/points.ply", "notes.txt"):
        (tmp_path / name).write_text("an earlier run's")
    (tmp_path / "reconstruction.json").write_text('{"conventions": "x"}')
    names = ("point_cloud.ply", "optic_flow.png", "model-*/points.ply", "reconstruction.json")
    folder = OutputFolder(tmp_path, inputs=[tmp_path / "reconstruction.json"], names=names)
    folder.check_free([tmp_path / "point_cloud.ply", tmp_path / "model-1" / "points.ply"])
    with pytest.raises(UsageError, match="one of its inputs"):
        folder.check_free([tmp_path / "reconstruction.json"])
    written = [tmp_path / "point_cloud.ply", tmp_path / "reconstruction.json"]
    assert sorted(folder.remove_stale(written)) == [tmp_path / "model-1" / "points.ply",
                                                    tmp_path / "optic_flow.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "point_cloud.ply",
                                                          "reconstruction.json"]


def test_a_workers_task_counts_say_task_for_one():
    from scene3D.cli.common import ran_tasks

    assert ran_tasks({"pairs": 43, "features": 1}) == "1 features task, 43 pairs tasks"
    assert ran_tasks({}) == "no tasks"
