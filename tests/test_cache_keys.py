"""Cache keys are derived from what each config field declares it changes (harness.run.config.keys).

Independent truth: the keys as they were written by hand before the derivation (the dicts below,
copied from that code), so existing cache entries keep their keys; and a field added in a test-only
subclass is in the keys it declares, and in no other.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.core.cameras import Camera
from harness.core.params import param
from harness.run.cache import StageCache, digest_json
from harness.run.config import parse_config
from harness.run.config.keys import KEYS, changes_of, key_inputs
from harness.run.config.reference import SECTIONS, reference
from harness.run.config.schema import config_param, declared
from harness.run.config.sections import CameraSpec, MethodEntry, Protocol, SceneSpec, Settings
from harness.run.runner import Runner
from harness.run.scene_views import scene_views
from harness.run.toolkit import Toolkit

REPO = Path(__file__).resolve().parent.parent

CONFIG = {"scenes": [{"name": "s", "source": "s.ply", "lod": 2, "n_test": 3}], "methods": ["random"],
          "protocol": {"renderer": "reference", "background": [0.5, 0.25, 1], "metrics": ["psnr", "ssim"],
                       "seed": 7, "device": "cpu", "aspect": 1.5, "longest_side": 64}, "ratios": [0.3]}
CAM = Camera.look_at((0, 0, 3), (0, 0, 0), width=8, height=6, fov_y_deg=50)


def _runner(tmp_path, protocol=None) -> Runner:
    cfg = parse_config(CONFIG, "c.yaml")
    if protocol is not None:
        cfg = dataclasses.replace(cfg, protocol=protocol)
    r = Runner(cfg, out_dir=tmp_path / "out", cache_root=tmp_path / "cache")
    r.versions = SimpleNamespace(renderer="R", metrics="M", pruner=lambda name: "P")
    return r


def _keys(r: Runner) -> dict[str, str]:
    item = SimpleNamespace(digest="D", train_digest="T")
    mv = parse_config(CONFIG, "c.yaml").methods[0]
    ref = r.ref_key(item, CAM)
    return {"render_ref": ref, "metrics": r.metrics_key(ref, "K"), "metrics_photo": r.metrics_key(ref, "K", "F"),
            "gt": r.gt_key(ref, "F"),
            "score": r._score_key(item, mv, SimpleNamespace(wants_cameras=lambda p: False)),
            "aware_score": r._score_key(item, mv, SimpleNamespace(wants_cameras=lambda p: True))}


def test_the_runner_keys_are_the_hand_written_ones(tmp_path):
    r = _runner(tmp_path)
    p, key = r.config.protocol, StageCache.key
    ref = key("render_ref", scene="D", camera=CAM.to_dict(), renderer=p.renderer, code="R",
              background=list(p.background))
    params = r.config.methods[0].params.to_dict()
    assert _keys(r) == {
        "render_ref": ref,
        "metrics": key("metrics", ref=ref, mask="K", metrics=list(p.metrics), code="M"),
        "metrics_photo": key("metrics", ref=ref, mask="K", metrics=list(p.metrics), code="M", photo="F"),
        "gt": key("gt", ref=ref, photo="F", metrics=list(p.metrics), code="M"),
        "score": key("score", scene="D", method="random", params=params, seed=7, code="P", cameras=None,
                     device=None),
        "aware_score": key("score", scene="D", method="random", params=params, seed=7, code="P", cameras="T",
                           device="cpu"),
    }


class _Recorder(StageCache):
    """A cache whose every ``views`` lookup hits, recording the key it was asked for."""

    def get_json(self, stage, key, **kw):
        self.asked = key
        return {"rig": "x", "train": [], "test": [], "held_out": None}


def test_the_view_keys_are_the_hand_written_ones(tmp_path):
    cfg = parse_config(CONFIG, "c.yaml")
    p, spec, versions = cfg.protocol, cfg.scenes[0], SimpleNamespace(rigs="V")
    cache = _Recorder(tmp_path / "cache")
    scene_views(spec, None, tmp_path, p, cache, Toolkit(resolve_dataset=lambda s: "x"), versions, "SD", tmp_path)
    source = {"rig": spec.rig, "scene": "SD", "dataset": "s.ply", "kind": spec.kind, "n_train": spec.n_train,
              "n_test": 3, "aspect": 1.5, "seed": 7}
    assert cache.asked == StageCache.key("views", source=source, longest_side=64, code="V")

    (tmp_path / "cams.json").write_text("[]")
    cams = CameraSpec(path="cams.json", test=("a", "b"), test_every=0)
    scene_views(dataclasses.replace(spec, cameras=cams), None, tmp_path, p, cache, Toolkit(), versions, "SD", tmp_path)
    source = {"cameras": cache.files.digest(tmp_path / "cams.json"), "test": ["a", "b"], "test_every": 0}
    assert cache.asked == StageCache.key("views", source=source, longest_side=64, code="V")


def test_the_other_layouts_are_the_hand_written_ones():
    spec = parse_config(CONFIG, "c.yaml").scenes[0]
    assert key_inputs("load", spec) == {"lod": 2}
    seq = dataclasses.replace(spec, sequence="seq", test=("v1",), test_every=0, width=640, height=480)
    assert key_inputs("sequence_views", seq) == {"source": {"test": ("v1",), "test_every": 0, "size": [640, 480]}}


def test_the_protocol_view_key_is_the_hand_written_one(tmp_path):
    from harness.run import protocol_views as pv
    from harness.views.protocols import protocol

    cfg = parse_config(CONFIG, "c.yaml")
    p, spec, cache = cfg.protocol, cfg.scenes[0], _Recorder(tmp_path / "cache")
    req = pv.request(spec, cfg, Toolkit(resolve_dataset=lambda s: "x"), tmp_path, held_out=lambda: [CAM])
    shifted = protocol("shifted")
    pv._cached(shifted, req, cache, "C", "SD", key_inputs("protocol_views", p, spec))
    source = {"scene": "SD", "held_out": digest_json([CAM.to_dict()]), "protocol": shifted.key(), "name": "s",
              "dataset": "s.ply", "rig": spec.rig, "kind": spec.kind, "n_train": spec.n_train, "n_test": 3,
              "aspect": 1.5, "seed": 7, "synthetic": True}
    assert cache.asked == StageCache.key("views", source=source, longest_side=64, code="C")


@dataclass(frozen=True)
class _Gamma(Protocol):
    gamma: float = config_param(2.2, doc="display gamma of the renders", changes=("render_ref",))


@dataclass(frozen=True)
class _Note(Protocol):
    note: str = config_param("", doc="a remark", changes=())


@dataclass(frozen=True)
class _Forgotten(Protocol):
    forgotten: int = param(0, doc="a field declared as a pruner parameter is, saying nothing of what it changes")


def test_a_new_field_is_in_the_keys_it_declares_and_in_no_other(tmp_path):
    base = _keys(_runner(tmp_path))
    p = _runner(tmp_path).config.protocol
    gamma = _keys(_runner(tmp_path, _Gamma(**{f.name: getattr(p, f.name) for f in declared(Protocol)})))
    changed = {k for k in base if base[k] != gamma[k]}
    assert changed == {"render_ref", "metrics", "metrics_photo", "gt"}  # the metrics keys hold the render's key
    assert _keys(_runner(tmp_path, _Note(**{f.name: getattr(p, f.name) for f in declared(Protocol)}))) == base
    with pytest.raises(TypeError, match="config field 'forgotten': declare what it changes"):
        _keys(_runner(tmp_path, _Forgotten(**{f.name: getattr(p, f.name) for f in declared(Protocol)})))


def test_every_field_of_every_section_declares_what_it_changes():
    for _, _, _, cls in SECTIONS:
        for f in declared(cls):
            assert set(changes_of(f)) <= {"content", *KEYS}, (cls.__name__, f.name)
    with pytest.raises(TypeError, match="changes='render' is no key"):
        changes_of(dataclasses.field(metadata={"changes": ("render",)}))


def test_method_and_top_level_fields_reach_the_keys_through_the_variants():
    """A methods[] entry and the top level change results only through what each variant carries
    (its method and resolved params in the score key, its ratios in the prune key): a new field of
    theirs that declares a key must be carried by the variants first."""
    carried = {(MethodEntry, "name"): ("score",), (MethodEntry, "params"): ("score",),
               (MethodEntry, "sweep"): ("score",), (MethodEntry, "ratios"): ("prune",),
               (MethodEntry, "keep"): ("prune",), (Settings, "ratios"): ("prune",), (Settings, "keep"): ("prune",)}
    keyed = {(cls, f.name): changes_of(f) for cls in (MethodEntry, Settings) for f in declared(cls) if changes_of(f)}
    assert keyed == carried, "wire the new field into MethodVariant and its key, then list it here"
    assert not [f.name for f in declared(SceneSpec) if "score" in changes_of(f)]  # no scene field reaches score


def test_the_config_reference_is_generated_from_the_declarations(capsys):
    from harness.cli import main

    regenerate = "regenerate it: harness config schema > docs/config.md"
    assert (REPO / "docs" / "config.md").read_text() == reference(), regenerate
    assert main(["config", "schema"]) == 0
    assert capsys.readouterr().out == reference()
    text = reference()
    for _, _, prefix, cls in SECTIONS:
        for f in declared(cls):
            assert f"`{prefix}{f.name}`" in text
    assert "| `protocol.renderer` | str | a registered name | `gl` | `render_ref` |" in text


def test_config_show_without_a_config_is_one_line(capsys):
    from harness.cli import main

    assert main(["config", "show"]) == 2
    err = capsys.readouterr().err
    assert "name the run config to show" in err and len(err.strip().splitlines()) == 1
