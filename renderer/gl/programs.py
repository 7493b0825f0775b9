"""Shader programs from the GLSL sources in shaders/ (package data `edgedog.shaders`)."""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources

import moderngl

SHADER_PACKAGE = "edgedog.shaders"


def shader_source(name: str) -> str:
    """The text of one shader file, e.g. "splats.vert"."""
    return (resources.files(SHADER_PACKAGE) / name).read_text(encoding="utf-8")


def with_defines(source: str, defines: Mapping[str, float]) -> str:
    """`source` with `#define NAME value` lines after its `#version` line (which must come first)."""
    version, _, body = source.partition("\n")
    lines = [f"#define {name} {float(value)!r}" for name, value in defines.items()]
    return "\n".join([version, *lines, body])


def load_program(ctx: moderngl.Context, name: str, defines: Mapping[str, float] | None = None
                 ) -> moderngl.Program:
    """Compile and link `<name>.vert` and `<name>.frag`, both given the same #defines.

    The Python constants stay the single source of truth: the shaders only name them.
    Raises moderngl.Error, naming the program, when a stage does not compile or link.
    """
    defines = defines or {}
    try:
        return ctx.program(vertex_shader=with_defines(shader_source(f"{name}.vert"), defines),
                           fragment_shader=with_defines(shader_source(f"{name}.frag"), defines))
    except moderngl.Error as error:
        raise moderngl.Error(f"shader program {name!r}: {error}") from error
