"""How far `edgedog sfm` has come, read from the lines it prints ("sfm: ..."), for the studio's
progress bar: its stage (features, matching, mapping, undistortion), how many photos it has and
how many of them it has registered.

The lines are those of `edgedog.scenes.sfm.run_sfm`; a line this module does not know only
becomes the last message shown (tests/test_app_sfm.py runs the real command and checks that every
stage is recognised).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

STAGES = ("features", "matching", "mapping", "undistortion")
"""The stages of `edgedog sfm`, in their order."""
PREFIX = "sfm: "
FEATURES = re.compile(r"extracting SIFT features from (\d+) photos")
MATCHING = re.compile(r"matching \(")
MAPPING = re.compile(r"(\d+) image pairs with .*incremental mapping")
REGISTERED = re.compile(r"\s*(\d+) images registered")
UNDISTORTING = re.compile(r".*: (\d+) of (\d+) photos, (\d+) points.*undistorting")
WROTE = re.compile(r"wrote ")


@dataclass(frozen=True)
class SfmProgress:
    """What the last lines said.

    Attributes:
        stage: index into STAGES, -1 before the first line, len(STAGES) once written.
        photos: how many photos it works on (None until said); registered: how many are
            registered so far; points: the sparse points of the model kept (once undistorting).
        message: the last line, without "sfm: ".
    """

    stage: int = -1
    photos: int | None = None
    registered: int = 0
    points: int | None = None
    message: str = "starting"

    @property
    def stage_name(self) -> str:
        if self.stage < 0:
            return "starting"
        return STAGES[self.stage] if self.stage < len(STAGES) else "done"

    @property
    def fraction(self) -> float:
        """Share of the work done: each stage a quarter, the mapping's by the photos registered."""
        if self.stage < 0:
            return 0.0
        within = 0.0
        if STAGES[min(self.stage, len(STAGES) - 1)] == "mapping" and self.photos:
            within = min(self.registered / self.photos, 1.0)
        return min((self.stage + within) / len(STAGES), 1.0)

    @property
    def label(self) -> str:
        """The progress bar's text, e.g. '3/4 mapping: 20 of 49 registered'."""
        if self.stage < 0 or self.stage >= len(STAGES):
            return self.stage_name
        text = f"{self.stage + 1}/{len(STAGES)} {self.stage_name}"
        if self.stage_name == "mapping" and self.photos:
            text += f": {self.registered} of {self.photos} registered"
        return text


def advance(progress: SfmProgress, line: str) -> SfmProgress:
    """The progress after one more line of the command's output (other lines leave it as it is)."""
    if not line.startswith(PREFIX):
        return progress
    message = line[len(PREFIX):].rstrip()
    changes: dict = {"message": message.strip()}
    if found := FEATURES.match(message):
        changes.update(stage=0, photos=int(found[1]))
    elif MATCHING.match(message):
        changes.update(stage=1)
    elif MAPPING.match(message):
        changes.update(stage=2)
    elif found := REGISTERED.match(message):
        changes.update(registered=int(found[1]))
    elif found := UNDISTORTING.match(message):
        changes.update(stage=3, registered=int(found[1]), photos=int(found[2]), points=int(found[3]))
    elif WROTE.match(message):
        changes.update(stage=len(STAGES))
    return dataclasses.replace(progress, **changes)
