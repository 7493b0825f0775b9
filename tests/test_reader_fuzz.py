"""Property tests of the readers a user's file reaches beyond JSON and YAML (those are in
test_document_reader.py): predicted edges (.obj, .ply, EMAP .json), primitives PLY, a NeRF scene's
transforms, a NeuS scene's cameras_sphere.npz, COLMAP text and binary models and a run's
checkpoint. Whatever the file holds, each ends in a value or in one
InputError line naming a file, never another exception.

Derandomized like test_document_reader.py (EXAMPLES examples per property, EDGEDOG_FUZZ_EXAMPLES
for more); the inputs mix a valid file's pieces with hostile ones, which reach further into a
reader than random bytes do.
"""

from __future__ import annotations

import io
import json
import shutil
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from edgedog.curve_files import read_edges
from edgedog.errors import InputError
from edgedog.primitives import read_ply
from edgedog.scenes import load_scene
from edgedog.train.checkpoint import read_checkpoint
from tests.helpers.fuzz import FUZZ, read_or_refuse
from tests.helpers.hostile_files import colmap_as_binary
from tests.helpers.scene_builders import make_colmap, make_nerf, make_neus, nerf_meta

NUMBERS = st.sampled_from(["0", "1", "-1", "0.5", "1e308", "-1e308", "nan", "inf", "1e-320", "999999999999",
                           "-0", "3", "2", "a", "", "1.5.5", "0x10"])


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """One folder for every example of the module: hypothesis reruns a test many times."""
    return tmp_path_factory.mktemp("fuzzed-files")


def obj_lines(numbers: list[str], kinds: list[str]) -> str:
    """OBJ text: `v`, `l` and other records of the given numbers."""
    lines, rest = [], iter(numbers)
    for kind in kinds:
        lines.append(" ".join([kind, *(next(rest, "1") for _ in range(3 if kind == "v" else 2))]))
    return "\n".join(lines) + "\n"


@FUZZ
@given(numbers=st.lists(NUMBERS, max_size=40),
       kinds=st.lists(st.sampled_from(["v", "l", "f", "#", "o", "vt", "g", "l 1 2 3 4"]), max_size=15))
def test_obj_of_any_records_is_curves_or_one_line(folder, numbers, kinds):
    read_or_refuse(read_edges, folder / "edges.obj", obj_lines(numbers, kinds).encode())


PLY_HEADERS = st.sampled_from([
    "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
    "element edge {m}\nproperty int vertex1\nproperty int vertex2\nend_header\n",
    "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
    "end_header\n",
    "ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
    "property float z\nend_header\n",
    "ply\nformat ascii 1.0\nelement vertex {n}\nproperty list uchar float x\nend_header\n",
    "ply\nformat ascii 1.0\nelement face {n}\nproperty float x\nend_header\n",
])


@FUZZ
@given(header=PLY_HEADERS, n=st.sampled_from(["0", "1", "2", "-1", "100000000000", "x"]),
       m=st.sampled_from(["0", "1", "-5", "99999999999"]), numbers=st.lists(NUMBERS, max_size=30),
       tail=st.binary(max_size=40))
def test_ply_of_any_header_and_body_is_read_or_one_line(folder, header, n, m, numbers, tail):
    content = header.format(n=n, m=m).encode() + " ".join(numbers).encode() + b"\n" + tail
    read_or_refuse(read_edges, folder / "edges.ply", content)
    read_or_refuse(read_ply, folder / "primitives.ply", content)


@FUZZ
@given(key=st.sampled_from(["curves_ctl_pts", "lines_end_pts", "other"]),
       value=st.recursive(st.sampled_from([0, 1.5, -1e300, "x", None, True, 10**30]),
                          lambda inner: st.lists(inner, max_size=13), max_leaves=60))
def test_emap_curves_of_any_shape_are_curves_or_one_line(folder, key, value):
    read_or_refuse(read_edges, folder / "edges.json", json.dumps({key: value}).encode())


@pytest.fixture(scope="module")
def nerf_scene(tmp_path_factory) -> Path:
    return make_nerf(tmp_path_factory.mktemp("fuzz-scene") / "scene")


FIELDS = st.sampled_from(["camera_angle_x", "frames", "file_path", "transform_matrix", "fl_x", "w", "h",
                          "camera_intrinsics", "aabb", "near"])
VALUES = st.recursive(st.sampled_from([0, 1, -1, 0.7, 1e300, "r_0", "../../etc/passwd", "", None, [], {}]),
                      lambda inner: st.lists(inner, max_size=5) | st.dictionaries(FIELDS, inner, max_size=3),
                      max_leaves=30)


@FUZZ
@given(edits=st.lists(st.tuples(st.sampled_from(["top", "frame"]), FIELDS, VALUES), min_size=1, max_size=4))
def test_nerf_transforms_with_any_field_changed_load_or_give_one_line(nerf_scene, edits):
    meta = nerf_meta(nerf_scene)
    for where, field, value in edits:
        target = meta["frames"][0] if where == "frame" and meta.get("frames") and \
            isinstance(meta["frames"], list) and isinstance(meta["frames"][0], dict) else meta
        target[field] = value
    transforms = nerf_scene / "transforms_train.json"
    original = transforms.read_bytes()
    try:
        transforms.write_text(json.dumps(meta))
        try:
            load_scene(nerf_scene)
        except InputError as error:
            assert "\n" not in str(error), str(error)
    finally:
        transforms.write_bytes(original)


@FUZZ
@given(content=st.binary(max_size=2000), zip_header=st.booleans())
def test_a_checkpoint_of_any_bytes_is_refused_in_one_line(folder, content, zip_header):
    path = folder / "checkpoint.pt"
    path.write_bytes((b"PK\x03\x04" if zip_header else b"") + content)
    with pytest.raises(InputError) as refused:
        read_checkpoint(path)
    assert str(refused.value).startswith(f"{path}: ") and "\n" not in str(refused.value)


SETTING_VALUES = st.recursive(st.sampled_from([0, 1, -1, 0.5, 1e300, 10**30, "x", "", None, True, "auto",
                                               "canny", "full"]),
                              lambda inner: st.lists(inner, max_size=4)
                              | st.dictionaries(st.sampled_from(["maps", "schedule", "epochs", "downscale",
                                                                 "init", "count", "x"]), inner, max_size=4),
                              max_leaves=25)


@FUZZ
@given(config=SETTING_VALUES, scene=st.sampled_from(["scene", 5, None]),
       version=st.sampled_from([1, 2, 3, 99, "3", None]),
       fingerprints=st.sampled_from([{}, {"scene_fingerprint": 5}, {"maps_fingerprint": "abc"}]))
def test_a_run_config_of_any_settings_is_a_run_or_one_line(folder, config, scene, version, fingerprints):
    from edgedog.train.run_folder import read_run

    run = folder / "run"
    run.mkdir(exist_ok=True)
    data = {"format": "edgedog-run", "version": version, "scene": scene, "config": config, **fingerprints}
    read_or_refuse(lambda path: read_run(path.parent), run / "config.json", json.dumps(data).encode())


@FUZZ
@given(suite=st.dictionaries(st.sampled_from(["scenes", "presets", "grid", "rows", "seeds", "set", "other"]),
                             SETTING_VALUES, max_size=5))
def test_a_suite_of_any_keys_is_a_suite_or_one_line(folder, suite):
    import yaml

    from edgedog.batch.suite import expand, load_suite

    def load(path):
        return expand(load_suite(path))

    read_or_refuse(load, folder / "suite.yaml", yaml.safe_dump(suite).encode())


def load_or_refuse(root: Path) -> None:
    """`load_scene(root)`: a scene, or one InputError line (never another exception)."""
    try:
        load_scene(root)
    except InputError as error:
        assert "\n" not in str(error), str(error)


@contextmanager
def replaced(path: Path, content: bytes):
    """`path` holding `content` for the block, its own bytes again after it."""
    original = path.read_bytes()
    try:
        path.write_bytes(content)
        yield
    finally:
        path.write_bytes(original)


def damaged(data: bytes, edits: list[tuple[int, bytes]], cut: int | None) -> bytes:
    """`data` with each (position, bytes) written over it (positions wrap) and cut at `cut`."""
    data = bytearray(data)
    for position, written in edits:
        at = position % (len(data) + 1)
        data[at:at + len(written)] = written
    return bytes(data if cut is None else data[:cut % (len(data) + 1)])


EDITS = st.lists(st.tuples(st.integers(0, 10**6),
                           st.sampled_from([b"\xff" * 8, b"\x00" * 8, (2**40).to_bytes(8, "little"), b"\x7f"])
                           | st.binary(min_size=1, max_size=8)), min_size=1, max_size=4)
CUT = st.none() | st.integers(0, 10**6)


@pytest.fixture(scope="module")
def neus_scene(tmp_path_factory) -> Path:
    return make_neus(tmp_path_factory.mktemp("fuzz-neus") / "scene")


ARRAYS = st.sampled_from([np.eye(4), np.zeros((4, 4)), np.full((4, 4), np.nan), np.full((4, 4), 1e308),
                          np.eye(3), np.zeros((4, 4, 4)), np.zeros(0), np.float64(1.0), np.eye(4,
                              dtype=np.int64),
                          np.eye(4, dtype=bool), np.eye(4, dtype=np.complex128), np.array(["a", "b"]),
                          np.array([None, {}], dtype=object), np.eye(4, dtype=np.float16)])
NEUS_KEYS = st.sampled_from(["world_mat_0", "world_mat_1", "scale_mat_0", "scale_mat_1", "world_mat_7",
    "other"])


@FUZZ
@given(arrays=st.dictionaries(NEUS_KEYS, ARRAYS, max_size=5), keep=st.booleans())
def test_neus_cameras_of_any_arrays_load_or_give_one_line(neus_scene, arrays, keep):
    """cameras_sphere.npz with any of its matrices replaced, removed or added (object arrays
    included: np.load(allow_pickle=False) must refuse them)."""
    path = neus_scene / "cameras_sphere.npz"
    with np.load(path) as archive:
        content = {key: archive[key] for key in archive.files} if keep else {}
    content.update(arrays)
    written = io.BytesIO()
    np.savez(written, **content)
    with replaced(path, written.getvalue()):
        load_or_refuse(neus_scene)


@FUZZ
@given(edits=EDITS, cut=CUT)
def test_neus_cameras_of_damaged_bytes_load_or_give_one_line(neus_scene, edits, cut):
    path = neus_scene / "cameras_sphere.npz"
    with replaced(path, damaged(path.read_bytes(), edits, cut)):
        load_or_refuse(neus_scene)


@pytest.fixture(scope="module")
def colmap_scenes(tmp_path_factory) -> dict[str, Path]:
    """A COLMAP project with a text model and a copy of it with the binary model."""
    text = make_colmap(tmp_path_factory.mktemp("fuzz-colmap") / "text")
    binary = tmp_path_factory.mktemp("fuzz-colmap") / "binary"
    shutil.copytree(text, binary)
    colmap_as_binary(binary)
    return {"text": text, "binary": binary}


TOKENS = st.sampled_from(["0", "1", "-1", "2", "1e308", "-1e308", "nan", "inf", "1e400",
    "99999999999999999999",
                          "0.5", "", "x", "PINHOLE", "FOV", "OPENCV", "a.png", "../../etc/passwd",
                              "1 2 3", "#"])


@FUZZ
@given(name=st.sampled_from(["cameras.txt", "images.txt", "points3D.txt"]),
       edits=st.lists(st.tuples(st.integers(0, 10**4), TOKENS), min_size=1, max_size=4))
def test_a_colmap_text_model_with_any_field_changed_loads_or_gives_one_line(colmap_scenes, name, edits):
    path = colmap_scenes["text"] / "sparse" / "0" / name
    lines = [line.split(" ") for line in path.read_text().splitlines()]
    fields = [(row, column) for row, line in enumerate(lines) if not line[0].startswith("#")
              for column in range(len(line))]
    for position, token in edits:
        if fields:
            row, column = fields[position % len(fields)]
            lines[row][column] = token
        else:
            lines.append([token])
    with replaced(path, "\n".join(" ".join(line) for line in lines).encode() + b"\n"):
        load_or_refuse(colmap_scenes["text"])


@FUZZ
@given(name=st.sampled_from(["cameras.bin", "images.bin", "points3D.bin", "rigs.bin", "frames.bin"]),
       edits=EDITS, cut=CUT)
def test_a_colmap_binary_model_of_damaged_bytes_loads_or_gives_one_line(colmap_scenes, name, edits, cut):
    """Counts of 2**64 - 1 included: pycolmap looped for ever on them before the bounds check
    (edgedog.scenes.colmap_binary)."""
    path = colmap_scenes["binary"] / "sparse" / "0" / name
    with replaced(path, damaged(path.read_bytes(), edits, cut)):
        load_or_refuse(colmap_scenes["binary"])
