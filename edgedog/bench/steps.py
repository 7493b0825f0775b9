"""`edgedog bench steps`: where a training step's time goes.

A whole run is trained as `edgedog train` trains it; torch.profiler records evenly spaced windows
of steps through it (the model's size changes over a run, so one window would not be typical).
Each step's stages are labelled in `Trainer.step` (`record_function`): the table gives each
stage's time per step (inclusive of the operators it calls) and the rest of the step (Python and
autograd glue between the stages), then the operators with the most time of their own, our
rasterizer's kernels among them. On a GPU the profiler records the device too: the kernels' time
per step, those with the most, and the kernel launches per step (a step there is bound by the
host's launches, not by the kernels). The profiler itself slows the recorded steps a
little; the run's own training time (log.json) is reported beside them.
"""

from __future__ import annotations

import warnings
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch.profiler import ProfilerActivity, profile, schedule

from edgedog.bench.tables import cell
from edgedog.errors import ConfigError
from edgedog.files import atomic_write_bytes, atomic_write_json
from edgedog.train.config import TrainConfig

STAGES = ("rasterize", "loss", "backward", "density statistics", "adam", "orientation losses",
          "density control", "checkpoint")
"""The labels of `Trainer.step`, in the order a step runs them ('loss' includes the pixel
uncertainty)."""
STEP_PREFIX = "ProfilerStep"
"""torch.profiler's label of each recorded step ("ProfilerStep*" in its averages)."""
TOP_OPERATORS = 15
LAUNCHES = ("cudaLaunchKernel", "cudaLaunchKernelExC", "cuLaunchKernel", "cuLaunchKernelEx")
"""The host-side events of a kernel launch (the runtime's and the driver's)."""
MAX_WINDOWS = 100
STEPS_FILES = ("steps.json", "steps.md")
"""What the bench writes into OUT beside OUT/run, its record first."""
MAX_WINDOW_STEPS = 1000


@dataclass
class StepProfile:
    """What the recorded steps spent, in seconds summed over them.

    steps: steps recorded; step_seconds: their wall time; stages: label -> inclusive time;
    operators: operator -> its own time (self CPU); train_seconds, total_steps: the whole run's
    training time (profiled steps included) and step count. With the device recorded (`device`):
    kernels, kernel -> its time on the device; launches, kernel launches.
    """

    steps: int = 0
    step_seconds: float = 0.0
    stages: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    operators: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    train_seconds: float = 0.0
    total_steps: int = 0
    device: bool = False
    kernels: dict[str, float] = field(default_factory=lambda: defaultdict(float))
    launches: int = 0

    def add_window(self, events) -> None:
        """Add one recorded window (`prof.key_averages()`)."""
        for event in events:
            seconds = event.cpu_time_total / 1e6
            if event.key.startswith(STEP_PREFIX):
                self.steps += event.count
                self.step_seconds += seconds
            elif event.key in STAGES:
                self.stages[event.key] += seconds
            elif event.key in LAUNCHES:
                self.launches += event.count
            elif event.is_user_annotation:  # the device's span of a label: idle gaps included
                continue
            elif event.self_cpu_time_total == 0 and event.self_device_time_total > 0:  # a kernel
                self.kernels[event.key] += event.self_device_time_total / 1e6
            else:
                self.operators[event.key] += event.self_cpu_time_total / 1e6

    def rows(self) -> list[dict]:
        """Per stage (and the rest of the step): ms per recorded step and share of the step."""
        per_step = 1000 / max(self.steps, 1)
        rest = self.step_seconds - sum(self.stages.values())
        named = [(stage, self.stages.get(stage, 0.0)) for stage in STAGES] + [("rest of the step", rest)]
        return [{"stage": stage, "ms_per_step": seconds * per_step,
                 "share": seconds / self.step_seconds if self.step_seconds else None}
                for stage, seconds in named]

    def top_operators(self, count: int = TOP_OPERATORS) -> list[dict]:
        return _top(self.operators, "operator", self.steps, count)

    def top_kernels(self, count: int = TOP_OPERATORS) -> list[dict]:
        return _top(self.kernels, "kernel", self.steps, count)

    def to_dict(self) -> dict:
        per_step = 1 / max(self.steps, 1)
        device = ({"launches_per_step": self.launches * per_step,
                   "kernel_ms_per_step": sum(self.kernels.values()) * 1000 * per_step,
                   "kernels": self.top_kernels()} if self.device else {})
        return {"recorded_steps": self.steps, "recorded_seconds": self.step_seconds,
                "train_seconds": self.train_seconds, "total_steps": self.total_steps,
                "stages": self.rows(), "operators": self.top_operators(), **device}


def _top(seconds_by_name: dict[str, float], label: str, steps: int, count: int) -> list[dict]:
    """The `count` names with the most seconds, each with its ms per step."""
    ranked = sorted(seconds_by_name.items(), key=lambda item: -item[1])[:count]
    return [{label: name, "ms_per_step": seconds * 1000 / max(steps, 1)} for name, seconds in ranked]


def window_schedule(total_steps: int, windows: int, window_steps: int):
    """A profiler schedule of `windows` windows of `window_steps` recorded steps (each after one
    warm-up step), spread evenly over `total_steps`."""
    if not 1 <= windows <= MAX_WINDOWS or not 1 <= window_steps <= MAX_WINDOW_STEPS:
        raise ConfigError(f"bench steps: --windows must be in [1, {MAX_WINDOWS}] and --window-steps in "
                          f"[1, {MAX_WINDOW_STEPS}], got {windows} and {window_steps}")
    cycle = total_steps // windows
    if cycle < window_steps + 1:
        raise ConfigError(f"bench steps: {windows} windows of {window_steps} steps (each after a warm-up "
                          f"step) do not fit in the run's {total_steps} steps")
    return schedule(wait=cycle - window_steps - 1, warmup=1, active=window_steps, repeat=windows)


def profile_training(run, windows: int, window_steps: int) -> StepProfile:
    """Train the open run (`edgedog.train.run.Run`) of one layer to its end, recording `windows`
    windows of `window_steps` steps, then write its outputs as `edgedog train` does."""
    trainer = run.current()
    total = trainer.total_steps - trainer.step_index
    on_gpu = trainer.device.type == "cuda"
    result = StepProfile(total_steps=total, device=on_gpu)
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if on_gpu else [])
    with warnings.catch_warnings(), profile(
            activities=activities, schedule=window_schedule(total, windows, window_steps),
            on_trace_ready=lambda prof: result.add_window(prof.key_averages())) as prof:
        # Each window is read when it ends, so that the profiler may forget it, as it warns it does.
        warnings.filterwarnings("ignore", message="Profiler clears events")
        while not trainer.done:
            trainer.step()
            prof.step()
    run.train()  # the layer is at its end: this writes its outputs, outside the recorded windows
    result.train_seconds = trainer.seconds
    return result


def run_steps_bench(scene_path: Path, out: Path, preset_name: str, config: TrainConfig, windows: int,
                    window_steps: int, progress: bool = True) -> StepProfile:
    """Train `config` on the scene into OUT/run (a new folder) with the profiler's windows, and
    write OUT/steps.json and OUT/steps.md."""
    from edgedog.train.lifecycle import START, lock_folder, plan_run
    from edgedog.train.run import open_run

    plan = plan_run(out / "run", scene_path, preset_name, config, START).check()
    with lock_folder(out), open_run(plan, progress) as run:
        result = profile_training(run, windows, window_steps)
        camera = run.scene.camera(0)
        summary = {"scene": str(run.scene.root), "preset": preset_name, "views": len(run.scene),
                   "size": [camera.width, camera.height], "threads": torch.get_num_threads(),
                   "final_primitives": len(run.trainer.model), **result.to_dict()}
        atomic_write_json(out / STEPS_FILES[0], summary)
        atomic_write_bytes(out / STEPS_FILES[1], markdown(summary).encode())
    return result


def markdown(summary: dict) -> str:
    """The stage table and the operator table of a `run_steps_bench` summary."""
    steps, total, seconds = summary["recorded_steps"], summary["total_steps"], summary["train_seconds"]
    recorded_ms = summary["recorded_seconds"] * 1000 / max(steps, 1)
    lines = [f"{steps} of {total} steps recorded ({recorded_ms:.1f} ms per recorded step; the run: "
             f"{seconds:.1f} s training, {seconds * 1000 / max(total, 1):.1f} ms per step, "
             f"{summary['threads']} threads).",
             ""]
    device = "kernels" in summary
    if device:
        lines += [f"On the device, per step: {summary['kernel_ms_per_step']:.2f} ms of kernels, "
                  f"{summary['launches_per_step']:.1f} kernel launches.", ""]
    lines += ["| stage | ms per step | share |", "|---|---|---|"]
    for row in summary["stages"]:
        share = None if row["share"] is None else 100 * row["share"]
        lines.append(f"| {row['stage']} | {cell(row['ms_per_step'], 2)} | {cell(share, 1)} % |")
    lines += ["", "| operator (own host time) | ms per step |", "|---|---|"]
    lines += [f"| `{row['operator']}` | {cell(row['ms_per_step'], 2)} |" for row in summary["operators"]]
    if device:
        lines += ["", "| kernel | ms per step |", "|---|---|"]
        lines += [f"| `{row['kernel'][:90]}` | {cell(row['ms_per_step'], 3)} |" for row in summary["kernels"]]
    return "\n".join(lines) + "\n"
