"""Preset files: every built-in preset round-trips through TOML and JSON to the same resolved
parameters, the shipped ``eyrc`` file holds the fitted example's values, and every problem of
a file is one line naming the file, the key and the value."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import pytest

from arenabench.generator.parameters.params import PARAMETERS, Range
from arenabench.generator.parameters.preset_files import (
    PRESET_SCHEMA,
    OpenParam,
    PresetFileError,
    ResolvedPreset,
    load_preset_file,
    preset_document,
    preset_to_toml,
    write_preset_file,
)
from arenabench.generator.parameters.presets import (
    EXAMPLE_SCENE,
    PRESET_FILES,
    PRESETS,
    builtin_preset,
    preset_key,
    resolve,
    resolve_preset,
)
from arenabench.limits import MAX_PRESET_FILE_BYTES


def _eyrc_text() -> str:
    p = builtin_preset("eyrc")
    return preset_to_toml(p.params, name=p.name, description=p.description,
                          evidence=p.evidence)


def _write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _set_line(text: str, key: str, line: str) -> str:
    """``text`` with the line of ``key`` (``tilt_deg = ...``, in its section) replaced."""
    new, n = re.subn(rf"^{re.escape(key)} = .*$", line, text, count=1, flags=re.M)
    assert n == 1, key
    return new


@pytest.mark.parametrize("fmt", ["toml", "json"])
@pytest.mark.parametrize("name", list(PRESETS))
def test_every_builtin_preset_round_trips_through_a_file(name, fmt, tmp_path):
    preset = builtin_preset(name)
    path = write_preset_file(tmp_path / f"{name}.{fmt}", preset.params, name=preset.name,
                             description=preset.description, evidence=preset.evidence)
    back = load_preset_file(path)
    assert back.params == preset.params == resolve(name)
    assert (back.name, back.description, back.evidence) == (name, preset.description,
                                                            preset.evidence)
    assert back.open == {} and back.source == path
    # and the types too: a float parameter stays a float, an int an int
    for key, value in back.params.items():
        assert type(value) is type(preset.params[key]), key


def test_eyrc_is_the_shipped_file_and_holds_the_fitted_example_values():
    """The eyrc preset's only source is its file; its camera, light and colours are the fitted
    example's (generator/scenes/task1c_example.json), as they were derived before."""
    assert set(PRESET_FILES) == {"eyrc"}
    shipped = load_preset_file(PRESET_FILES["eyrc"])
    assert shipped.name == "eyrc"
    assert dict(PRESETS["eyrc"][1]) == shipped.params
    assert PRESETS["eyrc"][0] == shipped.description
    ex = json.loads(EXAMPLE_SCENE.read_text())
    cam, light = ex["camera"], ex["lighting"]
    d = light["directional"][0]["direction"]
    grays = sorted({o["color_rgb"][0] for o in ex["obstacles"]})
    expected = {
        "arena.floor_rgb": tuple(ex["arena"]["floor_rgb"]),
        "obstacles.gray": grays[0] if len(grays) == 1 else Range(grays[0], grays[-1]),
        "camera.fov_deg": cam["fov_deg"], "camera.altitude_m": cam["altitude_m"],
        "camera.tilt_deg": cam["tilt_deg"], "camera.yaw_deg": cam["yaw_deg"],
        "camera.roll_deg": cam["roll_deg"], "camera.target_x_m": cam["target_m"][0],
        "camera.target_y_m": cam["target_m"][1],
        "lighting.ambient": light["ambient"],
        "lighting.intensity": light["directional"][0]["intensity"],
        "lighting.elevation_deg": round(math.degrees(math.asin(-d[2])), 6),
        "lighting.azimuth_deg": round(math.degrees(math.atan2(-d[1], -d[0])), 6),
        "background.gray": ex["background_rgb"][0],
        "arena.texture": "competition", "output.format": "jpeg", "output.jpeg_quality": 95,
        "obstacles.count": Range(1, 4), "obstacles.yaw_step_deg": 90.0,
    }
    for key, value in expected.items():
        assert shipped.params[key] == value, key
    assert shipped.evidence and isinstance(shipped.evidence, dict)


def test_a_written_file_is_commented_and_reads_back_as_written(tmp_path):
    text = _eyrc_text()
    assert text.splitlines()[3] == f'schema = "{PRESET_SCHEMA}"'
    assert "tilt_deg = 4.056331  # optical axis angle from the nadir (deg)" in text
    assert "count = [1, 4]  # number of boxes" in text
    doc = preset_document(builtin_preset("eyrc").params, name="eyrc")
    assert doc["camera"]["tilt_deg"] == 4.056331 and doc["obstacles"]["count"] == [1, 4]
    assert "open" not in doc and "evidence" not in doc["preset"]


def test_ranges_lists_aliases_and_dotted_keys_read_as_set_does(tmp_path):
    text = _eyrc_text()
    text = _set_line(text, "tilt_deg", 'tilt_deg = "0:2.5"')
    text = _set_line(text, "floor_rgb", 'floor_rgb = "240,241,242"')
    text = _set_line(text, "noise_sigma", "")  # given below by its alias
    text = _set_line(text, "altitude_m", "")  # given below as a quoted dotted key
    text = text.replace('schema = "', '"camera.altitude_m" = 3.5\nschema = "', 1)
    text += '\n[noise]\nsigma = 2\n'
    p = load_preset_file(_write(tmp_path, text))
    assert p.params["camera.tilt_deg"] == Range(0.0, 2.5)
    assert p.params["arena.floor_rgb"] == (240, 241, 242)
    assert p.params["degrade.noise_sigma"] == 2.0 and type(p.params["degrade.noise_sigma"]) is float
    assert p.params["camera.altitude_m"] == 3.5


def test_name_defaults_to_the_file_name(tmp_path):
    text = _eyrc_text().replace('name = "eyrc"\n', "")
    assert load_preset_file(_write(tmp_path, text, "lab-arena.toml")).name == "lab-arena"
    with pytest.raises(PresetFileError, match="no \\[preset\\] name"):
        load_preset_file(_write(tmp_path, text, "lab arena.toml"))


def _eyrc_with(tmp_path, block: str):
    """The eyrc preset file with ``block`` (``[open]`` entries) added, read back."""
    return load_preset_file(_write(tmp_path, _eyrc_text() + block))


def test_open_entries_are_stored_validated_and_written_back(tmp_path):
    p = _eyrc_with(tmp_path, '\n[open."lighting.azimuth_deg"]\nrange = [0.0, 360.0]\n'
                   'reason = "east and west faces not visible"\n'
                   '\n[open.output]\n'
                   'jpeg_quality = { values = [90, 95], reason = "one example" }\n')
    assert p.open == {
        "lighting.azimuth_deg": OpenParam("lighting.azimuth_deg",
                                          "east and west faces not visible",
                                          range=Range(0.0, 360.0)),
        "output.jpeg_quality": OpenParam("output.jpeg_quality", "one example", values=(90, 95)),
    }
    again = load_preset_file(write_preset_file(
        tmp_path / "again.toml", p.params, name=p.name, description=p.description,
        evidence=p.evidence, open=p.open))
    assert again == ResolvedPreset(p.name, p.params, p.description, p.evidence, p.open,
                                   source=tmp_path / "again.toml")
    doc = json.loads((write_preset_file(tmp_path / "again.json", p.params, name=p.name,
                                        open=p.open)).read_text())
    assert doc["open"]["lighting.azimuth_deg"] == {
        "range": [0.0, 360.0], "reason": "east and west faces not visible"}


def test_an_open_entry_names_what_moves_with_it(tmp_path):
    p = _eyrc_with(tmp_path, '\n[open."camera.fov_deg"]\nrange = [68.3, 70.6]\nmoves_with = '
                   '{ "camera.altitude_m" = [3.19, 3.06], "camera.tilt_deg" = [4.1, 3.9] }\n'
                   'reason = "the markers fit as well"\n')
    entry = p.open["camera.fov_deg"]
    assert entry.moves_with == (("camera.altitude_m", (3.19, 3.06)),
                                ("camera.tilt_deg", (4.1, 3.9)))
    assert entry.at(70.6) == {"camera.altitude_m": 3.06, "camera.tilt_deg": 3.9}
    with pytest.raises(ValueError, match="not an end of its range"):
        entry.at(69.0)
    again = load_preset_file(write_preset_file(tmp_path / "again.toml", p.params, name=p.name,
                                               open=p.open))
    assert again.open == p.open


MOVES_BAD = [
    ('moves_with = { "camera.altitud_m" = [3.1, 3.0] }', "unknown parameter (did you mean"),
    ('moves_with = { "camera.fov_deg" = [68.0, 69.0] }', "the entry's own parameter"),
    ('moves_with = { "camera.altitude_m" = [3.1] }', "2 numbers: the value at the range's"),
    ('moves_with = { "camera.tilt_deg" = [3.1, 95.0] }', "out of range"),
    ('moves_with = { "obstacles.count" = [1, 2] }', "draws obstacles.count per scene"),
    ('moves_with = { "markers.dictionary" = ["a", "b"] }', "is not a number"),
    ('moves_with = [1, 2]', "a table"),
]


@pytest.mark.parametrize("line,why", MOVES_BAD, ids=[w for _, w in MOVES_BAD])
def test_a_bad_moves_with_is_one_line(tmp_path, line, why):
    text = _eyrc_text() + ('\n[open."camera.fov_deg"]\nrange = [68.3, 70.6]\n' + line
                           + '\nreason = "the markers fit as well"\n')
    with pytest.raises(PresetFileError) as err:
        load_preset_file(_write(tmp_path, text))
    message = str(err.value)
    assert "\n" not in message and "open.camera.fov_deg.moves_with" in message
    assert why in message


def test_a_parameter_moves_with_one_other_at_most(tmp_path):
    base = _eyrc_text() + (
        '\n[open."camera.fov_deg"]\nrange = [68.3, 70.6]\n'
        'moves_with = { "camera.altitude_m" = [3.19, 3.06] }\nreason = "trade"\n')
    twice = base + ('\n[open."camera.tilt_deg"]\nrange = [3.0, 5.0]\n'
                    'moves_with = { "camera.altitude_m" = [3.1, 3.2] }\nreason = "trade"\n')
    with pytest.raises(PresetFileError, match=r"already moves with camera\.fov_deg"):
        load_preset_file(_write(tmp_path, twice))
    chained = base + ('\n[open."camera.altitude_m"]\nrange = [3.0, 3.3]\n'
                      'moves_with = { "camera.tilt_deg" = [3.1, 3.2] }\nreason = "trade"\n')
    with pytest.raises(PresetFileError, match="has a moves_with of its own"):
        load_preset_file(_write(tmp_path, chained))
    # a values entry: one value per listed value, in their order
    values = _eyrc_text() + ('\n[open."lighting.azimuth_deg"]\nvalues = [79.999431, 90.0, 180.0]\n'
                             'moves_with = { "lighting.ambient" = [0.59167, 0.2, 0.4] }\n'
                             'reason = "the light"\n')
    entry = load_preset_file(_write(tmp_path, values)).open["lighting.azimuth_deg"]
    assert entry.at(90.0) == {"lighting.ambient": 0.2}
    with pytest.raises(PresetFileError, match="3 numbers: the value at each of the 3 values"):
        load_preset_file(_write(tmp_path, values.replace("0.2, 0.4]", "0.2]")))


def test_the_preset_rule_names_and_files(tmp_path, monkeypatch):
    assert resolve_preset("eyrc-hard") == builtin_preset("eyrc-hard")
    path = _write(tmp_path, _eyrc_text(), "mine.toml")
    assert resolve_preset(str(path)).params == builtin_preset("eyrc").params
    monkeypatch.chdir(tmp_path)
    assert resolve_preset("mine.toml").source == Path("mine.toml")
    with pytest.raises(ValueError, match=r"unknown preset 'eyrx' \(did you mean 'eyrc'\?\)"):
        resolve_preset("eyrx")
    with pytest.raises(ValueError, match=r"preset file nope\.toml: no such file"):
        resolve_preset("nope.toml")
    (tmp_path / "afolder").mkdir()
    with pytest.raises(ValueError, match=r"preset file \./afolder: a folder"):
        resolve_preset("./afolder")


def test_key_is_the_name_for_the_builtin_values_else_name_and_hash(tmp_path):
    assert preset_key(builtin_preset("eyrc")) == "eyrc"
    same = load_preset_file(_write(tmp_path, _eyrc_text()))
    assert preset_key(same) == "eyrc"
    other = load_preset_file(_write(tmp_path, _set_line(_eyrc_text(), "tilt_deg",
                                                        "tilt_deg = 5.0")))
    assert re.fullmatch(r"eyrc-[0-9a-f]{10}", preset_key(other))


# ------------------------------------------------------------------------ one line per problem

BAD = [
    # (edit of the eyrc file, what the one line must hold)
    (("tilt_deg", "tlt_deg = 4.0"),
     "camera.tlt_deg = 4.0: unknown parameter (did you mean 'camera.tilt_deg'?)"),
    (("tilt_deg", "tilt_deg = 95.0"), "camera.tilt_deg = 95.0: value 95.0 out of range [0, 79]"),
    (("tilt_deg", 'tilt_deg = "4"'),
     'camera.tilt_deg = "4": a string where a number belongs'),
    (("tilt_deg", "tilt_deg = { lo = 1 }"),
     "camera.tilt_deg = { lo = 1 }: a table where a value belongs"),
    (("tilt_deg", "tilt_deg = [5.0, 1.0]"), "camera.tilt_deg = [5.0, 1.0]: empty range"),
    (("tilt_deg", 'tilt_deg = "5:1"'), 'camera.tilt_deg = "5:1": empty range'),
    (("tilt_deg", "tilt_deg = [1.0, 2.0, 3.0]"), "a range is two numbers [lo, hi]"),
    (("tilt_deg", "tilt_deg = nan"), "camera.tilt_deg = nan: invalid float value"),
    (("tilt_deg", "tilt_deg = true"), "camera.tilt_deg = true: a boolean where a number"),
    (("count", "count = 2.5"), "obstacles.count = 2.5: invalid int value"),
    (("markers_in_view", 'markers_in_view = "yes"'),
     'camera.markers_in_view = "yes": a string where true or false belongs'),
    (("floor_rgb", "floor_rgb = [1, 2]"), "arena.floor_rgb = [1, 2]: expected 3"),
    (("floor_rgb", "floor_rgb = [1.5, 2, 3]"), "arena.floor_rgb = [1.5, 2, 3]: expected three"),
    (("texture", 'texture = "marble"'), 'arena.texture = "marble": invalid value'),
    (("dictionary", "dictionary = 4"), "markers.dictionary = 4: a number where a string"),
    (("ids", "ids = [80, 80, 90, 95]"), "the four corners' ids must differ"),
]


@pytest.mark.parametrize(("edit", "needle"), BAD, ids=[b[1][:40] for b in BAD])
def test_each_bad_value_is_one_line_naming_file_key_and_value(edit, needle, tmp_path):
    path = _write(tmp_path, _set_line(_eyrc_text(), *edit))
    with pytest.raises(PresetFileError) as exc:
        load_preset_file(path)
    message = str(exc.value)
    assert "\n" not in message
    assert message.startswith(f"preset file {path}: "), message
    assert needle in message, message


BAD_DOCS = [
    ("\n[camra]\ntilt_deg = 1.0\n", "unknown table [camra] (did you mean 'camera'?)"),
    ('\n[preset2]\nname = "x"\n', "unknown table [preset2]"),
    ('\n[open."camera.tlt_deg"]\nrange = [0.0, 1.0]\nreason = "r"\n',
     "open.camera.tlt_deg = { range = [0.0, 1.0], reason = \"r\" }: unknown parameter "
     "(did you mean 'camera.tilt_deg'?)"),
    ('\n[open."camera.tilt_deg"]\nrange = [0.0, 10.0]\n', "needs a reason"),
    ('\n[open."camera.tilt_deg"]\nrange = [10.0, 0.0]\nreason = "r"\n',
     "open.camera.tilt_deg.range = [10.0, 0.0]: empty range"),
    ('\n[open."camera.tilt_deg"]\nrange = [5.0, 10.0]\nreason = "r"\n',
     "the preset's own camera.tilt_deg = 4.056331 is not among what it allows"),
    ('\n[open."camera.tilt_deg"]\nrange = [0.0, 10.0]\nvalues = [1.0, 2.0]\nreason = "r"\n',
     "needs range = [lo, hi] or values = [...], one of them"),
    ('\n[open."arena.texture"]\nrange = [0, 1]\nreason = "r"\n', "is not a number"),
    ('\n[open."arena.texture"]\nvalues = ["competition", "marble"]\nreason = "r"\n',
     'open.arena.texture.values = "marble": invalid value'),
    ('\n[open."camera.tilt_deg"]\nrange = [0.0, 10.0]\nreason = "r"\nwhy = "w"\n',
     "open.camera.tilt_deg.why = \"w\": unknown key of an [open] entry"),
    ('\n[open]\n"camera.tilt_deg" = 3\n', "an [open] entry is a table"),
    ('\n[degrade]\n', None),  # a second [degrade] table: TOML itself refuses it
    ('\n[noise]\nsigma = 1.0\n', "noise.sigma = 1.0: given twice (also as degrade.noise_sigma)"),
]


@pytest.mark.parametrize(("tail", "needle"), BAD_DOCS, ids=[b[0][:30] for b in BAD_DOCS])
def test_each_bad_table_is_one_line(tail, needle, tmp_path):
    path = _write(tmp_path, _eyrc_text() + tail)
    with pytest.raises(PresetFileError) as exc:
        load_preset_file(path)
    message = str(exc.value)
    assert "\n" not in message and message.startswith(f"preset file {path}: "), message
    assert needle is None or needle in message, message


def test_preset_table_problems(tmp_path):
    def fails(text: str, needle: str) -> None:
        with pytest.raises(PresetFileError, match=re.escape(needle)):
            load_preset_file(_write(tmp_path, text))

    text = _eyrc_text()
    fails(text.replace('name = "eyrc"', 'name = "a b"'), 'preset.name = "a b": a preset name')
    fails(text.replace('name = "eyrc"', 'nmae = "x"'),
          "preset.nmae = \"x\": unknown key of [preset] (did you mean 'name'?)")
    fails(text.replace('[preset.evidence]', '[preset.evidence]\nwhen = 2024-01-01'),
          "preset.evidence.when = 2024-01-01: a date (write it as a string)")
    fails(text.replace(f'schema = "{PRESET_SCHEMA}"', ""), "no schema key")
    fails(text.replace(PRESET_SCHEMA, "arenabench.preset/9"),
          'schema = "arenabench.preset/9": this arenabench reads "arenabench.preset/1"')
    fails(f'schema = "{PRESET_SCHEMA}"\n[camera]\ntilt_deg = 1.0\n', "missing parameters: ")
    fails(text.replace("[preset]", "foo = 1\n[preset]"), "foo = 1: unknown key (a preset file")
    fails(text.replace("[preset]", '"output.foo" = 1\n[preset]'),
          "output.foo = 1: unknown parameter (did you mean 'output.format'?)")


def test_unreadable_files_are_one_line(tmp_path):
    cases = {
        "syntax.toml": (b"schema = \n", "not valid TOML"),
        "latin.toml": ("name = 'é'".encode("latin-1"), "not UTF-8 text"),
        "nan.json": (b'{"schema": NaN}', "not valid JSON: NaN is not a number"),
        "list.json": (b"[1, 2]", "must hold a JSON object, got list"),
        "big.toml": (b"#" * (MAX_PRESET_FILE_BYTES + 1),
                     f"more than the {MAX_PRESET_FILE_BYTES} bytes allowed"),
    }
    for name, (data, needle) in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(PresetFileError) as exc:
            load_preset_file(path)
        assert "\n" not in str(exc.value) and needle in str(exc.value), (name, str(exc.value))
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(PresetFileError, match="cannot read it: not a regular file"):
        resolve_preset(str(fifo))  # never blocks on the FIFO
    with pytest.raises(PresetFileError, match="cannot read it"):
        load_preset_file(tmp_path / "gone.toml")


def test_writing_refuses_what_reading_refuses(tmp_path):
    params = builtin_preset("eyrc").params
    with pytest.raises(ValueError, match="preset name"):
        write_preset_file(tmp_path / "x.toml", params, name="no spaces")
    with pytest.raises(ValueError, match="out of range"):
        write_preset_file(tmp_path / "x.toml", {**params, "camera.tilt_deg": 99.0}, name="x")
    with pytest.raises(ValueError, match="needs a reason"):
        write_preset_file(tmp_path / "x.toml", params, name="x",
                          open={"camera.tilt_deg": {"range": [0.0, 9.0]}})
    assert not (tmp_path / "x.toml").exists()
    # a partial mapping gets the neutral values of what it leaves out
    partial = {k: v for k, v in params.items() if PARAMETERS[k].neutral != v}
    assert len(partial) < len(params)
    back = load_preset_file(write_preset_file(tmp_path / "p.toml", partial, name="p"))
    assert back.params == params
