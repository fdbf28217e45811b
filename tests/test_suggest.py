"""The shared 'did you mean' wording."""

from harness.core.suggest import close_matches, did_you_mean, unknown


def test_close_match_is_named_and_known_names_listed():
    msg = unknown("scene name", "luigii", ["luigi", "playbot", "grape-small"])
    assert msg == "unknown scene name 'luigii' (did you mean 'luigi'?); known: luigi, playbot, grape-small"


def test_case_insensitive_and_original_spelling_returned():
    assert close_matches("LUIGI", ["luigi"]) == ["luigi"]
    assert close_matches("Bonsai-7K", ["bonsai-7k", "bonsai-7k-mini"])[0] == "bonsai-7k"


def test_nothing_close_gives_no_suggestion():
    assert did_you_mean("zzz", ["alpha", "beta"]) == ""
    assert unknown("metric", "zzz", ["psnr"]) == "unknown metric 'zzz'; known: psnr"


def test_two_suggestions_joined_with_or():
    assert did_you_mean("opacty", ["opacity", "opacity2"]) == " (did you mean 'opacity' or 'opacity2'?)"
