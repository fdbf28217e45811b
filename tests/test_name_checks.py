"""Every list of a config that names scenes, methods, metrics, tables, plots or protocols: a typo in
it is reported as the entry that is unknown, with a known name suggested — never the reverse."""

from __future__ import annotations

import copy

import pytest

from harness.core.errors import InputError
from harness.run.config import parse_config

BASE = {"scenes": ["luigi", "grape-small"], "ratios": [0.1], "protocols": ["rig", "shifted"],
        "methods": ["opacity", {"name": "random", "scenes": ["luigi"], "protocols": ["rig"]}]}

CASES = [
    ({"methods": ["opacty"]}, "methods[0].name: unknown method 'opacty' (did you mean 'opacity'?)"),
    ({"methods": [{"name": "random", "scenes": ["luigii"]}]},
     "methods[0].scenes[0]: unknown scene of this config 'luigii' (did you mean 'luigi'?)"),
    ({"methods": [{"name": "random", "protocols": ["shiftd"]}]},
     "methods[0].protocols[0]: unknown protocol of this config 'shiftd' (did you mean 'shifted'?)"),
    ({"protocol": {"metrics": ["lpipss"]}}, "protocol.metrics[0]: unknown metric or metric set 'lpipss' "
                                            "(did you mean 'lpips'?)"),
    ({"tables": ["comparsion"]}, "tables[0]: unknown table 'comparsion' (did you mean 'comparison'?)"),
    ({"plots": ["curvs"]}, "plots[0]: unknown plot 'curvs' (did you mean 'curves'?)"),
    ({"protocols": ["rig", "shiftd"]}, "protocols[1]: unknown view protocol 'shiftd' (did you mean 'shifted'?)"),
    ({"anchor": "lightgss"}, "anchor: unknown method 'lightgss' (did you mean 'lightgs'?)"),
    # the scene list itself misspelt while a method's list holds the right name: the typo is blamed
    ({"scenes": ["luigii", "grape-small"]},
     "scenes[0] 'luigii': unknown scene name 'luigii' (did you mean 'luigi'?)"),
]


@pytest.mark.parametrize(("over", "message"), CASES, ids=[next(iter(o)) for o, _ in CASES])
def test_a_typo_names_the_unknown_entry_and_a_known_name(over, message):
    doc = copy.deepcopy(BASE)
    doc.update(over)
    with pytest.raises(InputError) as info:
        parse_config(doc, "c.yaml")
    assert str(info.value).startswith(f"c.yaml: {message}"), str(info.value)


def test_a_misspelt_scene_of_the_default_study_is_blamed_not_the_method_lists(tmp_path):
    """The issue's case: `luigii` in a copy of default.yaml's `scenes:`, which its sensitivity
    sweeps name correctly."""
    from harness.core.paths import REPO_ROOT
    from harness.run.config import load_config

    text = (REPO_ROOT / "ctc_configs" / "default.yaml").read_text()
    assert "- {name: luigi, kind: object-centric}" in text
    (tmp_path / "default.yaml").write_text(text.replace("- {name: luigi, kind:", "- {name: luigii, kind:"))
    with pytest.raises(InputError) as info:
        load_config(tmp_path / "default.yaml")
    message = str(info.value)
    assert "'luigii' (did you mean 'luigi'?)" in message and "'luigi' (did you mean" not in message, message


def test_a_scene_given_by_path_is_not_taken_for_a_misspelt_name():
    """A method list naming a scene the config lacks, beside a scene given by a file path: the
    method's entry is the unknown one."""
    doc = copy.deepcopy(BASE)
    doc["scenes"] = [{"name": "mine", "source": "scenes/luigii.ply"}, "grape-small"]
    with pytest.raises(InputError, match=r"methods\[1\]\.scenes\[0\]: unknown scene of this config 'luigi'"):
        parse_config(doc, "c.yaml")
