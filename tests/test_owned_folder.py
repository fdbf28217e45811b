"""One command owns an output folder (harness.io.owned): the lock, its holder in the refusal, a lock
left by a killed process, staging and publishing as one step, a publication killed before and after
its decision, the folder that is not a run's, inputs never deleted, and the commands that take it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from harness.cli import main
from harness.core.errors import InputError
from harness.io.owned import LOCK, PUBLISHING, STAGING, OwnedFolder, reading


def test_a_second_owner_is_refused_naming_the_first(tmp_path):
    with OwnedFolder(tmp_path / "out", "harness run a.yaml"):
        with pytest.raises(InputError, match=r"is being written by harness run a\.yaml \(pid \d+ on .+, since "):
            with OwnedFolder(tmp_path / "out", "harness run b.yaml"):
                pass
        with pytest.raises(InputError, match="is being written by harness run a.yaml"):
            with reading(tmp_path / "out"):
                pass
    with OwnedFolder(tmp_path / "out", "harness run b.yaml"):  # released at the end
        pass
    with reading(tmp_path / "out"):
        pass


def test_a_lock_left_by_a_killed_process_is_taken(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    code = (f"import time; from harness.io.owned import OwnedFolder\n"
            f"with OwnedFolder({str(out)!r}, 'victim'):\n    print('held', flush=True); time.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert p.stdout.readline().strip() == "held"
    with pytest.raises(InputError, match="being written by victim"):
        OwnedFolder(out, "second").__enter__()
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert (out / LOCK).exists()  # the file stays, unlocked
    with OwnedFolder(out, "second"):
        assert json.loads((out / LOCK).read_text())["command"] == "second"


def _published(folder: OwnedFolder, **files) -> None:
    stage = folder.stage(carry=("records",))
    for rel, text in files.items():
        (stage / rel).parent.mkdir(parents=True, exist_ok=True)
        (stage / rel).write_text(text)
    folder.publish(["results.csv", "tables", "records"])


def test_a_publication_replaces_entries_whole_and_carries_records(tmp_path):
    out = tmp_path / "out"
    with OwnedFolder(out, "first") as f:
        _published(f, **{"results.csv": "one", "tables/a.md": "A1", "tables/old.md": "stale", "records/1.json": "r1"})
    with OwnedFolder(out, "second") as f:
        _published(f, **{"results.csv": "two", "tables/a.md": "A2", "records/2.json": "r2"})
    assert (out / "results.csv").read_text() == "two"
    assert sorted(p.name for p in (out / "tables").iterdir()) == ["a.md"]  # no table of the first run left
    assert (out / "tables" / "a.md").read_text() == "A2"
    assert sorted(p.name for p in (out / "records").iterdir()) == ["1.json", "2.json"]
    assert not (out / STAGING).exists() and not (out / PUBLISHING).exists()


def test_a_publication_killed_before_its_decision_leaves_the_old_outputs(tmp_path):
    out = tmp_path / "out"
    with OwnedFolder(out, "first") as f:
        _published(f, **{"results.csv": "one", "tables/a.md": "A1"})
    f = OwnedFolder(out, "killed").__enter__()
    stage = f.stage()
    (stage / "results.csv").write_text("two")
    os.close(f._fd)  # killed here: its staging folder stays behind
    with OwnedFolder(out, "next"):
        assert not (out / STAGING).exists()
    assert (out / "results.csv").read_text() == "one" and (out / "tables" / "a.md").read_text() == "A1"


def test_a_publication_killed_after_its_decision_is_finished_by_the_next_owner(tmp_path, monkeypatch):
    import harness.io.owned as owned

    out = tmp_path / "out"
    with OwnedFolder(out, "first") as f:
        _published(f, **{"results.csv": "one", "tables/a.md": "A1"})
    moves = []

    def dies_after_one(src, dst, replaced):
        if moves:
            raise KeyboardInterrupt  # killed between two moves
        moves.append(dst.name)
        real_move(src, dst, replaced)

    real_move = owned._move_in
    monkeypatch.setattr(owned, "_move_in", dies_after_one)
    f = OwnedFolder(out, "killed").__enter__()
    stage = f.stage()
    (stage / "tables").mkdir()
    (stage / "tables" / "a.md").write_text("A2")
    (stage / "results.csv").write_text("two")
    with pytest.raises(KeyboardInterrupt):
        f.publish(["results.csv", "tables"])
    os.close(f._fd)
    assert (out / PUBLISHING).is_dir() and len(moves) == 1  # half of it in place: the next owner finishes
    monkeypatch.setattr(owned, "_move_in", real_move)
    with OwnedFolder(out, "next"):
        pass
    assert (out / "results.csv").read_text() == "two" and (out / "tables" / "a.md").read_text() == "A2"
    assert not (out / PUBLISHING).exists()


def test_a_folder_that_is_not_a_run_folder_is_refused_before_anything_is_written(tmp_path):
    (tmp_path / "images").mkdir()
    (tmp_path / "images" / "mine.png").write_bytes(b"x")
    with pytest.raises(InputError, match="holds images but is not a harness run folder"):
        OwnedFolder(tmp_path, "harness run", owns=("images", "tables")).__enter__()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["images"]  # not even a lock file
    (tmp_path / "run.json").write_text("{}")  # a run folder of older code
    with OwnedFolder(tmp_path, "harness run", owns=("images", "tables")):
        pass


def test_an_input_inside_a_replaced_entry_is_never_deleted(tmp_path):
    from harness.io.safe import read_bytes, recording_inputs

    out = tmp_path / "out"
    with OwnedFolder(out, "first") as f:
        _published(f, **{"tables/config.yaml": "name: x"})
    with recording_inputs(), OwnedFolder(out, "second") as f:
        read_bytes(out / "tables" / "config.yaml", "config", "config")
        f.stage()
        (out / STAGING / "tables").mkdir()
        with pytest.raises(InputError, match="would overwrite the input"):
            f.publish(["tables"])
    assert (out / "tables" / "config.yaml").read_text() == "name: x"


def test_a_carried_record_read_while_staging_is_moved_not_refused(tmp_path):
    """The page reads the earlier runs' records carried into the staging folder (hard links of the
    ones the publication replaces): they move with it, so reading them does not make the old entry
    an input that may not be deleted (every second run into a folder was refused)."""
    from harness.io.safe import read_bytes, recording_inputs

    out = tmp_path / "out"
    with OwnedFolder(out, "first") as f:
        _published(f, **{"records/1.json": "r1"})
    with recording_inputs(), OwnedFolder(out, "second") as f:
        stage = f.stage(carry=("records",))
        read_bytes(stage / "records" / "1.json", "json", "run record")
        (stage / "records" / "2.json").write_text("r2")
        f.publish(["records"])
    assert sorted(p.name for p in (out / "records").iterdir()) == ["1.json", "2.json"]


def test_tables_and_report_take_the_runs_lock(tmp_path, capsys):
    from tests.stress.cases import _run_dir

    run = _run_dir(tmp_path)
    with OwnedFolder(run, "harness run c.yaml"):
        for command in (["tables", str(run)], ["report", str(run)]):
            assert main(command) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and "is being written by harness run c.yaml" in err[0], err
    assert main(["report", str(run)]) == 0
    assert (run / "report.html").is_file() and not (run / STAGING).exists()
    assert main(["tables", str(tmp_path / "absent")]) == 2
    assert "absent: no such folder" in capsys.readouterr().err and not (tmp_path / "absent").exists()


def test_a_second_run_into_one_folder_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    from tests.stress.cases import _config

    monkeypatch.chdir(tmp_path)
    cfg = _config(tmp_path)
    with OwnedFolder(tmp_path / "out", "harness run other.yaml"):
        t0 = time.perf_counter()
        assert main(["run", str(cfg), "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "cache")]) == 2
        assert time.perf_counter() - t0 < 30
    err = capsys.readouterr().err.strip().splitlines()
    assert "is being written by harness run other.yaml" in err[-1]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [LOCK]
