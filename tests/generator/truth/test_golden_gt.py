"""Golden GT hashes: the same (preset, seed, index) gives the same ground truth unless
GENERATOR_VERSION says otherwise (docs/architecture.md, "Golden GT")."""

import json

import golden
import pytest


def test_ground_truth_matches_the_golden_hashes_of_this_generator_version():
    version = golden.generator_version()
    recorded = golden.load()
    assert version in recorded, (
        f"tests/data/golden_gt.json has no hashes for GENERATOR_VERSION {version!r} "
        f"(it has {sorted(recorded)}): regenerate it with `{golden.UPDATE_COMMAND}`"
    )
    diff = golden.differences(recorded[version], golden.current())
    assert not diff, (
        "ground truth changed while GENERATOR_VERSION is still "
        f"{version!r}:\n  " + "\n  ".join(diff) + "\n"
        "If the change is intended: bump GENERATOR_VERSION in generator/dataset/make.py (say what "
        f"changed in its comment) and regenerate the golden file with `{golden.UPDATE_COMMAND}`"
        " (or `make golden`)."
    )


def test_every_preset_has_golden_scenes():
    from arenabench.generator.parameters.presets import preset_names

    keys = golden.current()
    assert {k.split("/")[0] for k in keys} == set(preset_names())
    assert len(keys) == golden.SCENES_PER_PRESET * len(preset_names())


def test_hashes_ignore_float_noise_and_ring_start_but_see_real_changes():
    gt = golden.scene_gt("eyrc", 0)
    base = golden.gt_parts(gt)
    noisy = json.loads(json.dumps(gt))
    noisy["area"]["visible_px"] += 1e-9
    ring = noisy["obstacles"][0]["visible_frame_px"]
    noisy["obstacles"][0]["visible_frame_px"] = ring[2:] + ring[:2]
    assert golden.gt_parts(noisy) == base
    moved = json.loads(json.dumps(gt))
    moved["obstacles"][0]["visible_frame_px"][0][0] += 0.01
    moved["count"] += 1
    parts = golden.gt_parts(moved)
    assert {p for p in base if parts[p] != base[p]} == {"obstacles", "count"}


@pytest.mark.integration
def test_update_refuses_to_change_the_hashes_of_a_recorded_version(tmp_path, monkeypatch,
                                                                   capsys):
    path = tmp_path / "golden_gt.json"
    monkeypatch.setattr(golden, "GOLDEN_PATH", path)
    stale = {key: {**parts, "area": "0" * 16} for key, parts in golden.current().items()}
    path.write_text(json.dumps({golden.generator_version(): stale}))
    before = path.read_text()
    assert golden.main(["--update"]) == 1
    err = capsys.readouterr().err
    assert "bump GENERATOR_VERSION" in err and "eyrc/0: area changed" in err
    assert path.read_text() == before
    assert golden.main(["--update", "--force"]) == 0
    assert golden.main([]) == 0
    # A new version is written without --force, and only the current version is kept.
    path.write_text(json.dumps({"0-old": stale}))
    assert golden.main(["--update"]) == 0
    assert list(json.loads(path.read_text())) == [golden.generator_version()]
