"""Write a built twin into a folder: ``preset.toml``, ``scene.json``, ``twin.json``,
``report.html`` (and ``textures/<sha256>.png``, the arena texture, when the arena is an image:
what both ``preset.toml`` and ``scene.json`` name, relative to the folder).

Every file is first written into a staging folder inside the output folder, then moved into
place, ``twin.json`` last: a folder holding ``twin.json`` holds a whole twin, and an
interrupted or failed run leaves the earlier twin (or nothing) as it was.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from arenabench.fileio import dumps_json
from arenabench.generator.assets.texture_store import TEXTURES_FOLDER
from arenabench.generator.fitting.build import Twin
from arenabench.generator.fitting.records import TWIN_SCHEMA
from arenabench.generator.parameters.preset_files import write_preset_file
from arenabench.interrupts import deferred_stops

#: What a twin folder holds (``textures/`` only with an image texture), ``twin.json`` last.
TWIN_FILES = (TEXTURES_FOLDER, "preset.toml", "scene.json", "report.html", "twin.json")


def write_preset(path: Path, twin: Twin, *, name: str, evidence: dict[str, Any]) -> Path:
    """The twin's preset file (the one place the preset format is chosen: the preset files'
    writer, :func:`arenabench.generator.parameters.preset_files.write_preset_file`, which copies an
    image texture beside the file, to ``textures/<sha256>.png``, and names it so)."""
    params = dict(twin.params)
    description = (f"twin of {twin.facts['image']['file']}: its camera, light, greys, arena "
                   "and edges held, the boxes varied around what it shows")
    return write_preset_file(path, params, name=name, description=description,
                             evidence=evidence, open=twin.open_params)


def twin_document(twin: Twin, *, name: str) -> dict[str, Any]:
    """``twin.json``'s content."""
    return {
        "schema": TWIN_SCHEMA,
        "name": name,
        **twin.facts,
        "parameters": {r.name: r.to_dict() for r in twin.records},
        "varied": [{"parameter": v.name, "seen": v.seen, "rule": v.rule} for v in twin.varied],
        "timings_s": twin.timings,
    }


def _evidence(twin: Twin) -> dict[str, Any]:
    f = twin.facts
    return {
        "image": f["image"]["file"],
        "made_by": "arenabench twin",
        "markers": f"{f['markers']['dictionary']} {f['markers']['ids']}, printed "
                   f"{f['markers']['rotation_deg']:g} deg",
        "camera": f"fitted to the markers ({f['camera']['stage']}), snapped: "
                  + (", ".join(f"{k} {v['value']:g} {v['unit']}"
                               for k, v in f["camera"]["snapped"].items()) or "none"),
        "fit": f"marker squares {f['figures']['mad']['markers']:.2f} grey levels from the "
               f"image, whole image {f['figures']['whole']:.2f}",
        "verdict": twin.verdict.line().removeprefix("fit: "),
        "open": ", ".join(sorted(twin.open_params)) or "none",
        **({"scale": "open: the image fixes lengths only up to one scale (no --arena-size or "
                     "texture); the twin's lengths are in units of the generator's default "
                     "arena, and at any scale, every length scaled alike, its images and "
                     "answers are the same"}
           if f["scale"]["source"] == "default" else {}),
    }


def write_twin(out: Path, twin: Twin, *, name: str) -> list[Path]:
    """Write ``twin`` into ``out`` (created; its lock is the caller's), replacing an earlier
    twin's files. Returns the files written."""
    from arenabench.generator.fitting.report import report_html

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stage: Path | None = None
    try:
        with deferred_stops():  # a stop lands before the staging folder is made or once named
            stage = Path(tempfile.mkdtemp(prefix=".twin-", suffix=".tmp", dir=out))
        written = []
        # an image texture's reference, textures/<sha256>.png, is also its path in the folder
        write_preset(stage / "preset.toml", twin, name=name, evidence=_evidence(twin))
        if (stage / TEXTURES_FOLDER).is_dir():
            written.append(TEXTURES_FOLDER)
        (stage / "scene.json").write_text(dumps_json(twin.scene.to_dict()), encoding="utf-8")
        (stage / "report.html").write_text(report_html(twin, name=name), encoding="utf-8")
        (stage / "twin.json").write_text(dumps_json(twin_document(twin, name=name)),
                                         encoding="utf-8")
        written += ["preset.toml", "scene.json", "report.html", "twin.json"]
        if (out / "twin.json").exists():  # an earlier twin's files go, twin.json first
            (out / "twin.json").unlink()
        for old in TWIN_FILES:
            if (out / old).is_dir() and not (out / old).is_symlink():
                shutil.rmtree(out / old)
            elif os.path.lexists(out / old):
                (out / old).unlink()
        for item in written:
            os.replace(stage / item, out / item)
        return [out / item for item in written]
    finally:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
