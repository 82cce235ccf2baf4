"""Blind round trips drawn from every preset's space: the hidden image is a scene of a preset
(``eyrc``, ``eyrc-jitter``, ``eyrc-upright``, ``eyrc-oblique``, ``eyrc-hard``, ``warehouse``)
made exactly as ``arenabench generate`` makes it (its degradations, distractors, shadows and
file format), some with marker families or a lens no preset draws (:data:`VARIANTS`). The twin
is given the image file alone.

Unlike :mod:`twin_blind`'s own cases, these hold what the twin does not model (sensor noise,
blur, vignetting, exposure, lens distortion, tapes and papers, cast shadows), so the test is of
the verdict: a ``good`` twin must hold every bound against what was hidden
(:func:`compare_preset`), and a case whose image the twin cannot reproduce must be called
``poor``, never ``good``. ``tools/twin_round_trips.py --presets`` runs all
:data:`PRESET_CASES` per preset and prints the table; ``tests/generator/fitting/
test_twin_blind.py`` one case of each preset.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin_blind import TOLERANCES, _camera_px, same_family

from arenabench.generator.parameters.params import Value

#: The presets drawn from: every named preset.
BLIND_PRESETS = ("eyrc", "eyrc-jitter", "eyrc-upright", "eyrc-oblique", "eyrc-hard",
                 "warehouse")
#: Cases per preset (``tools/twin_round_trips.py --presets``): 42 in all.
PRESET_CASES = 7
#: What a case changes beyond its preset's draws (case number modulo :data:`PRESET_CASES`
#: -> ``--set`` values), for marker families and lenses no preset draws; not for ``eyrc``,
#: whose markers are printed on the competition's texture.
VARIANTS: dict[int, dict[str, Value]] = {
    2: {"markers.dictionary": "DICT_APRILTAG_36h11", "markers.ids": (3, 17, 42, 101)},
    4: {"camera.k1": -0.06, "camera.k2": 0.01},
    5: {"markers.dictionary": "DICT_5X5_250", "markers.ids": (7, 61, 130, 222),
        "markers.rotation_deg": 90.0},
    6: {"markers.dictionary": "DICT_APRILTAG_25h9", "markers.ids": (1, 9, 20, 33),
        "camera.k1": 0.04},
}
#: Parameters whose effect the twin does not render (:func:`hidden_features`): name ->
#: (what it is, the value at which it is absent).
UNMODELLED: dict[str, tuple[str, float]] = {
    "degrade.noise_sigma": ("noise", 0.0),
    "degrade.poisson_photons": ("photon noise", 0.0),
    "degrade.motion_blur_px": ("motion blur", 0.0),
    "degrade.defocus_px": ("defocus", 0.0),
    "degrade.vignetting": ("vignetting", 0.0),
    "degrade.exposure_ev": ("exposure", 0.0),
    "degrade.gamma": ("gamma", 1.0),
    "camera.k1": ("lens k1", 0.0),
    "camera.k2": ("lens k2", 0.0),
    "camera.k3": ("lens k3", 0.0),
    "camera.p1": ("lens p1", 0.0),
    "camera.p2": ("lens p2", 0.0),
    "distractors.tapes": ("tapes", 0.0),
    "distractors.papers": ("papers", 0.0),
    "lighting.shadow_strength": ("shadows", 0.0),
    "lighting.spot_strength": ("spot light", 0.0),
    "markers.occlusion": ("marker occlusion", 0.0),
}


@dataclass(frozen=True)
class PresetCase:
    """A hidden scene drawn from a preset.

    Attributes
    ----------
    preset : str
        The preset's name.
    number : int
        The case's number (its seed; scene 0 of that seed).
    overrides : dict
        ``--set`` values beyond the preset's draws (:data:`VARIANTS`).
    """

    preset: str
    number: int
    overrides: dict[str, Value] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """``PRESET-NUMBER``."""
        return f"{self.preset}-{self.number}"


def preset_case(preset: str, number: int) -> PresetCase:
    """Case ``number`` of ``preset`` (its variant: :data:`VARIANTS`)."""
    variant = {} if preset == "eyrc" else VARIANTS.get(number % PRESET_CASES, {})
    return PresetCase(preset=preset, number=number, overrides=dict(variant))


def preset_cases(per_preset: int = PRESET_CASES) -> list[PresetCase]:
    """Cases ``1..per_preset`` of every preset of :data:`BLIND_PRESETS`."""
    return [preset_case(p, n) for p in BLIND_PRESETS for n in range(1, per_preset + 1)]


@dataclass(frozen=True)
class Hidden:
    """What was hidden in a case's image: its scene, the sampled parameters, the image file
    and its ground truth."""

    scene: Any
    params: dict[str, Any]
    image: Path
    gt: dict[str, Any]


def write_preset_case(case: PresetCase, folder: Path, renderer) -> Hidden:
    """Make ``case`` (scene 0 of seed ``number``) as ``arenabench generate`` makes it and
    write its image file, encoded as its preset says, into ``folder``."""
    from arenabench.generator.dataset.make import make_sample
    from arenabench.generator.model.sampler import sample_scene

    overrides = case.overrides or None
    sampled = sample_scene(case.preset, seed=case.number, index=0, overrides=overrides)
    sample = make_sample(case.preset, seed=case.number, index=0, overrides=overrides,
                         renderer=renderer)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    image = folder / f"hidden-{case.name}.{sample.output.ext}"
    image.write_bytes(sample.image_bytes)
    return Hidden(scene=sampled.scene, params=dict(sampled.params), image=image, gt=sample.gt)


def hidden_features(params: dict[str, Any]) -> list[str]:
    """What the sampled ``params`` hold that the twin does not render, as ``name value``."""
    out = []
    for key, (what, absent) in UNMODELLED.items():
        value = params.get(key, absent)
        if isinstance(value, (int, float)) and not math.isclose(float(value), absent,
                                                                 abs_tol=1e-9):
            out.append(f"{what} {value:g}")
    return out


def _quarter_turns(hidden_ids: list[int], twin_ids: list[int]) -> int | None:
    """The quarter turns of the corners that take the hidden ids (in corner order) to the
    twin's, or None. The twin names the corners from the image alone: a world turned by a
    quarter turn with its camera is the same image, and equally the arena."""
    for q in range(4):
        if hidden_ids[q:] + hidden_ids[:q] == twin_ids:
            return q
    return None


def compare_preset(case: PresetCase, hidden_case: Hidden, twin_dir: Path) -> dict[str, Any]:
    """The twin in ``twin_dir`` set against ``case``'s hidden scene (``sample``): markers,
    camera (image px), boxes seen, marker squares; and whether its verdict is right: ``good``
    holding every check, or ``poor`` where a check fails or the image holds what the twin does
    not render (:func:`hidden_features`). A ``poor`` twin that holds every check of an image
    with nothing unrendered is ``cautious``: not wrong, counted apart."""
    from arenabench.generator.model.scene import load_scene

    doc = json.loads((Path(twin_dir) / "twin.json").read_text())
    twin = load_scene(Path(twin_dir) / "scene.json")
    hidden = hidden_case.scene
    checks: dict[str, tuple[Any, Any, bool]] = {}

    def check(name: str, want: Any, got: Any, ok: bool) -> None:
        checks[name] = (want, got, bool(ok))

    check("markers.dictionary", hidden.markers.dictionary, doc["markers"]["dictionary"],
          same_family(hidden.markers.dictionary, doc["markers"]["dictionary"]))
    quarters = _quarter_turns(list(hidden.markers.ids), doc["markers"]["ids"])
    check("markers.ids (corner order, up to quarter turns)", list(hidden.markers.ids),
          doc["markers"]["ids"], quarters is not None)
    px = min(_camera_px(hidden, twin.camera, twin.arena.side_m, turn_deg=sign * 90.0 * q)
             for q in (quarters or 0,) for sign in (1, -1))
    check("camera (image px)", 0.0, round(px, 3), px <= TOLERANCES["camera_px"][0])
    check("obstacles seen", len(hidden.obstacles), len(twin.obstacles),
          len(hidden.obstacles) == len(twin.obstacles))
    mad = doc["figures"]["mad"]["markers"]
    check("marker squares (grey levels)", TOLERANCES["marker_squares"][0], mad,
          mad <= TOLERANCES["marker_squares"][0])
    features = hidden_features(hidden_case.params)
    held = all(ok for _, _, ok in checks.values())
    verdict = doc["verdict"]["verdict"]
    if verdict == "good":
        right = "right" if held else "WRONG"
    else:
        right = "right" if (not held or features) else "cautious"
    return {"case": case.name, "checks": checks, "held": held, "features": features,
            "verdict": verdict, "causes": doc["verdict"]["causes"], "judged": right,
            "ok": right != "WRONG", "marker_squares": mad}


def preset_round_trip(case: PresetCase, folder: Path, renderer) -> dict[str, Any]:
    """Write ``case``'s image into ``folder``, run ``arenabench twin`` on it alone (a
    subprocess; its twin in ``folder/twin``) and :func:`compare_preset`. A twin that refuses
    the image in one line (exit 2, nothing written) is recorded as ``refused``, with its line."""
    hidden = write_preset_case(case, folder, renderer)
    out = Path(folder) / "twin"
    proc = subprocess.run([sys.executable, "-m", "arenabench", "twin", str(hidden.image), "--out",
                           str(out), "--no-progress"], capture_output=True, text=True)
    if proc.returncode == 2 and not out.exists():
        lines = proc.stderr.strip().splitlines()
        return {"case": case.name, "checks": {}, "held": False,
                "features": hidden_features(hidden.params), "verdict": "refused",
                "causes": [{"kind": "refused", "text": t} for t in lines[-1:]],
                "judged": "right" if len(lines) == 1 else "WRONG",
                "ok": len(lines) == 1, "marker_squares": float("nan"), "hidden": hidden}
    if proc.returncode not in (0, 6):
        raise AssertionError(f"case {case.name}: arenabench twin exited {proc.returncode}: "
                             f"{proc.stderr.strip()}")
    return {**compare_preset(case, hidden, out), "hidden": hidden}


def reference_passes_image(hidden: Hidden) -> bool:
    """Whether the reference pipeline passes the hidden image itself (visible area
    reference): only then does the twin's pass rate have a bound."""
    from arenabench.competition import DEFAULT_TOLERANCE
    from arenabench.eval.datasets.reader import DatasetItem
    from arenabench.eval.pipelines import make_pipeline
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.imageio import load_image

    item = DatasetItem(id="hidden", image_path=hidden.image, gt_path=Path("hidden.json"),
                       gt=hidden.gt)
    pred = make_pipeline("reference").run_image(load_image(hidden.image))
    return bool(score_image(item.truth(area_reference="visible"), pred,
                            tolerance=DEFAULT_TOLERANCE).passed)

