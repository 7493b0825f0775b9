"""The bounded JSON and YAML reader (edgedog.files.read_json, read_yaml): property tests with
hypothesis, and the bounds themselves (size, depth, digits, finite numbers, devices and FIFOs).

Every property: a file holding anything ends in its value or in one InputError line naming it,
never another exception. Hypothesis runs derandomized (tests/helpers/fuzz.py: the same examples on
every run, CI included; EDGEDOG_FUZZ_EXAMPLES for a larger budget).
"""

from __future__ import annotations

import json
import os
import string
from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from edgedog.errors import InputError
from edgedog.files import MAX_DEPTH, MAX_DOCUMENT_BYTES, MAX_INT_DIGITS, read_bounded, read_json, read_yaml
from tests.helpers.fuzz import FUZZ, read_or_refuse

# Plain data as edgedog's files hold it: finite floats, integers of at most MAX_INT_DIGITS digits.
SCALARS = (st.none() | st.booleans() | st.text(max_size=20)
           | st.integers(min_value=-10**MAX_INT_DIGITS + 1, max_value=10**MAX_INT_DIGITS - 1)
           | st.floats(allow_nan=False, allow_infinity=False))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=5)
                      | st.dictionaries(st.text(max_size=8), inner, max_size=5), max_leaves=40)
# Text made of JSON's and YAML's own tokens: more likely than random bytes to get deep into a parser.
TOKENS = st.sampled_from(["[", "]", "{", "}", ",", ":", '"', "\\", "1", "-", "e", "E", "1e999",
                          "NaN", "Infinity", "-Infinity", "0" * 120, "9" * 5000, "true", "null",
                          " ", "\n", "- ", "  ", "&a", "*a", "!!python/object:os.system", ".inf",
                          "---", "? ", "|", "#", "'", "\x00", "é"])
TOKEN_TEXT = st.lists(TOKENS, max_size=60).map("".join)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """One folder for every example of the module: hypothesis reruns a test many times."""
    return tmp_path_factory.mktemp("documents")


def depth(value) -> int:
    if isinstance(value, dict):
        value = list(value.values())
    return 1 + max(map(depth, value), default=0) if isinstance(value, list) else 0


@FUZZ
@given(value=VALUES)
def test_json_reads_back_what_json_writes(folder, value):
    assert read_or_refuse(read_json, folder / "value.json", json.dumps(value).encode()) == value


@FUZZ
@given(value=VALUES)
def test_yaml_reads_back_what_yaml_writes(folder, value):
    assert read_or_refuse(read_yaml, folder / "value.yaml", yaml.safe_dump(value).encode()) == value


@FUZZ
@given(content=st.binary(max_size=300))
def test_json_of_any_bytes_is_a_value_or_one_line(folder, content):
    read_or_refuse(read_json, folder / "bytes.json", content)


@FUZZ
@given(content=st.binary(max_size=300))
def test_yaml_of_any_bytes_is_a_value_or_one_line(folder, content):
    read_or_refuse(read_yaml, folder / "bytes.yaml", content)


@FUZZ
@given(text=TOKEN_TEXT)
def test_json_of_token_soup_is_a_bounded_value_or_one_line(folder, text):
    value = read_or_refuse(read_json, folder / "tokens.json", text.encode())
    assert depth(value) <= MAX_DEPTH


@FUZZ
@given(text=TOKEN_TEXT)
def test_yaml_of_token_soup_is_a_bounded_value_or_one_line(folder, text):
    value = read_or_refuse(read_yaml, folder / "tokens.yaml", text.encode())
    assert depth(value) <= MAX_DEPTH


@FUZZ
@given(levels=st.integers(min_value=0, max_value=3 * MAX_DEPTH),
       key=st.text(string.ascii_letters, max_size=3))
def test_nesting_is_read_up_to_the_cap_and_refused_beyond(folder, levels, key):
    value = 0
    for _ in range(levels):
        value = {key: value} if key else [value]
    for read, name, text in ((read_json, "deep.json", json.dumps(value)),
                             (read_yaml, "deep.yaml", yaml.safe_dump(value))):
        result = read_or_refuse(read, folder / name, text.encode())
        assert (result == value) if levels <= MAX_DEPTH else result is None, (name, levels)


@pytest.mark.parametrize("read, suffix", [(read_json, "json"), (read_yaml, "yaml")])
@pytest.mark.parametrize("number, problem", [
    ("9" * (MAX_INT_DIGITS + 1), "digits"), ("9" * 5000, "digits"), ("-" + "9" * 4301, "digits"),
    ("1.0e+999", "finite"), ("-1.0e+400", "finite")])
def test_numbers_beyond_the_bounds_are_refused_with_their_place(folder, read, suffix, number, problem):
    path = folder / f"number.{suffix}"
    path.write_text(f'{{"frames": [{{"x": 1}}, {{"x": {number}}}]}}')
    with pytest.raises(InputError, match=problem) as refused:
        read(path)
    if read is read_json or len(number) < 4000:  # YAML refuses longer ones before building a value
        assert str(refused.value).startswith(f"{path}: frames[1].x "), str(refused.value)


@pytest.mark.parametrize("read, suffix, text", [
    (read_json, "json", '{"a": NaN}'), (read_json, "json", "[Infinity]"), (read_json, "json", "[-Infinity]"),
    (read_yaml, "yaml", "a: .nan"), (read_yaml, "yaml", "[.inf]"), (read_yaml, "yaml", "[-.Inf]")])
def test_nan_and_infinity_are_refused(folder, read, suffix, text):
    (folder / f"constant.{suffix}").write_text(text)
    with pytest.raises(InputError, match="finite numbers"):
        read(folder / f"constant.{suffix}")


def test_yaml_aliases_and_python_tags_are_refused(folder):
    for text, words in (("a: &x [1]\nb: *x\n", "alias"), ("a: &x [*x]\n", "alias"),
                        ("a: !!python/object/apply:os.system ['true']\n", "invalid YAML")):
        (folder / "tags.yaml").write_text(text)
        with pytest.raises(InputError, match=words):
            read_yaml(folder / "tags.yaml")


def test_a_file_is_read_up_to_the_size_cap_and_refused_beyond(folder):
    path = folder / "big.json"
    with open(path, "wb") as file:  # sparse: costs no disk
        file.truncate(MAX_DOCUMENT_BYTES + 1)
    with pytest.raises(InputError, match="larger than 64 MiB"):
        read_json(path)
    path.write_bytes(b"[" + b" " * 1000 + b"]")
    assert read_bounded(path, limit=1002) == path.read_bytes()
    with pytest.raises(InputError, match="larger than"):
        read_bounded(path, limit=1001)


@pytest.mark.parametrize("read", [read_json, read_yaml])
def test_devices_fifos_folders_and_missing_files_are_refused_unread(folder, read):
    (folder / "zero").unlink(missing_ok=True)
    (folder / "zero").symlink_to("/dev/zero")
    if not (folder / "fifo").exists():
        os.mkfifo(folder / "fifo")  # no writer: opening it to read would block forever
    (folder / "dir").mkdir(exist_ok=True)
    for name, words in (("zero", "not a regular file"), ("fifo", "not a regular file"),
                        ("dir", "is a folder"), ("missing", "file not found")):
        with pytest.raises(InputError, match=words):
            read(folder / name)
