"""What the property tests of the readers share: hypothesis settings that give the same examples on
every run (CI included), and the check that a reader's refusal is one InputError line."""

from __future__ import annotations

import os
from pathlib import Path

from hypothesis import HealthCheck, settings

from edgedog.errors import InputError

EXAMPLES = int(os.environ.get("EDGEDOG_FUZZ_EXAMPLES", "150"))
"""Examples per property; set EDGEDOG_FUZZ_EXAMPLES for a larger budget
(`EDGEDOG_FUZZ_EXAMPLES=5000 pytest tests/test_document_reader.py --hypothesis-show-statistics`)."""
FUZZ = settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def read_or_refuse(read, path: Path, content: bytes):
    """`read(path)` of a file holding `content`: its value, or None after checking that the
    refusal is one InputError line naming the file."""
    path.write_bytes(content)
    try:
        return read(path)
    except InputError as error:
        assert str(error).startswith(f"{path}: ") and "\n" not in str(error), str(error)
        return None
