"""Where a lit view's colour pass spends its time: the same scenes drawn with one piece of the lit
surface shader cut out at a time, same run. ``python -m benchmarks.shader_cost [--config P]
[--size HxW] [--samples N] [--rounds R]`` from the repository root.

Each cut replaces one piece of our GLSL (``sidar_torch/render/shaders``) by something almost free, as
text, in this process only (:data:`CUTS`); the renderer is otherwise the package's. The pixels of a
cut are wrong, so only time is read: the colour step of ``SceneRenderer.render``'s timings (the lit
draw of every surface, ``glFinish`` ed; shadow maps, read-back and the rest are other steps), per view.
What a cut saves is what that piece costs, including whatever the shader compiler could drop only
because of it; the savings of two cuts need not add up.

Every cut gets a renderer of its own, which first draws every measured sequence once with its cut in
place (programs are compiled at first use); the rounds then draw each sequence with each renderer
in turn, and a sequence's figure is its fastest round (the least disturbed by other jobs). It prints
the median over sequences, wall clock, with the load beside it.

    python -m benchmarks.shader_cost --size 384x512 --samples 12 --rounds 3
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
from typing import Iterator

from sidar_torch import SidarDataset, load_config
from sidar_torch.timing import collect_timings

from .common import DEFAULT_PRESET, machine, machine_line, parse_set, parse_size, size_label

__all__ = ["CUTS", "build_parser", "cut_applied", "main"]

Replacement = tuple[str, str, str]
"""``(shader file, its text, what replaces it)``."""

CUTS: dict[str, tuple[str, tuple[Replacement, ...]]] = {
    "none": ("the package's shader", ()),
    "lights": ("every light: the loops over light groups and emitters, their shading and shadow lookups "
               "(ambient light only)", (
                   ("surface.frag", "#ifdef SPOT_LIGHT_SHADOWS\n    for (int g = 0; g < lookup_begin;",
                    "#if 1\n#elif defined(SPOT_LIGHT_SHADOWS)\n    for (int g = 0; g < lookup_begin;"),)),
    "shading": ("each light group's shading (cone, distance, the two GGX lobes and the diffuse term); "
                "the loops and lookups stay", (
                    ("group_shade.glsl", "vec3 shade = spot_light(g, n, roughness, metallic, f0, c_diff, base_color.rgb, l);",
                     "vec3 shade = c_diff; l = n;"),)),
    "lookups": ("the shadow-map lookups (every emitter lit)", (
        ("spot_shadow.glsl", "float spot_shadow(int i, mat4 light_matrix, int layer, float nl)\n{\n",
         "float spot_shadow(int i, mat4 light_matrix, int layer, float nl)\n{\n    return 0.0;\n"),)),
    "texture": ("the painting's texture read and its sRGB decoding", (
        ("surface.frag", "base_color = base_color * srgb_to_linear(painting_texel(material.base_color_texture, uv_0));",
         "base_color = base_color * vec4(uv_0, 0.5, 1.0);"),)),
    "encoding": ("the sRGB encoding of the output (its power)", (
        ("surface_output.glsl", "return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));",
         "return c;"),)),
    "everything": ("the whole fragment stage (a constant colour): what is left is rasterisation, the depth "
                   "test and the writes", (
                       ("surface.frag", "void main()\n{\n",
                        "void main()\n{\n    frag_color = vec4(0.5);\n#ifdef SHADOW_FREE\n"
                        "    shadow_free_color = vec4(0.5);\n#endif\n    return;\n"),)),
}
"""Name -> (what it cuts, its replacements). Each replaced text must occur exactly once in its file."""


@contextlib.contextmanager
def cut_applied(replacements: tuple[Replacement, ...]) -> Iterator[None]:
    """Within the block, programs compiled in this process read our shader files with ``replacements``
    made (``render.programs.glsl`` wrapped).

    Raises:
        ValueError: a replaced text does not occur exactly once in its file (the shader changed since
            the cut was written: the cut must be updated, not silently skipped).
    """
    from sidar_torch.render import programs  # imports OpenGL: here, so parsing loads no GL

    original = programs.glsl
    for name, old, _ in replacements:
        count = (programs.SHADER_DIR / name).read_text().count(old)
        if count != 1:
            raise ValueError(f"shader_cost: {name} holds the cut text {count} times, expected once: {old!r}")

    def cut_glsl(name: str) -> str:
        text = original.__wrapped__(name)  # read afresh (glsl caches its texts), its includes through cut_glsl
        for file, old, new in replacements:
            if file == name:
                text = text.replace(old, new)
        return text

    programs.glsl = cut_glsl
    try:
        yield
    finally:
        programs.glsl = original


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.shader_cost``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.shader_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config field (repeatable), e.g. --set n_lights=[1,1]")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=12, help="sequences drawn (default 12)")
    parser.add_argument("--rounds", type=int, default=3, help="times each renderer draws each sequence (default 3)")
    return parser


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Print the colour step's median ms per view for every cut; returns them by cut name."""
    from sidar_torch.render import RenderSettings, SceneRenderer  # imports pyrender: here, so parsing loads no GL

    args = build_parser().parse_args(argv)
    try:
        config = load_config(args.config, image_size=args.size, **parse_set(args.set))
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"shader_cost: {error}") from error
    before = machine()
    dataset = SidarDataset(config=config, seed=0)
    work = [(dataset.scene(k), dataset.source.painting(k % len(dataset.source), config.image_size))
            for k in range(args.samples)]
    renderers = {}
    for name, (_, replacements) in CUTS.items():
        with cut_applied(replacements):
            renderer = SceneRenderer(RenderSettings.from_config(config))
            for sequence, painting in work:
                renderer.render(sequence, painting)
        renderers[name] = renderer, renderer.program_count
    colour_ms: dict[str, list[float]] = {name: [float("inf")] * len(work) for name in CUTS}
    try:
        for _ in range(args.rounds):
            for k, (sequence, painting) in enumerate(work):
                for name, (renderer, _) in renderers.items():
                    with collect_timings() as timings:
                        renderer.render(sequence, painting)
                    colour_ms[name][k] = min(colour_ms[name][k], 1e3 * timings["colour"] / len(sequence.views))
        for name, (renderer, programs) in renderers.items():
            if renderer.program_count != programs:  # a program compiled after its cut was removed
                raise RuntimeError(f"shader_cost: the {name!r} renderer compiled a program while measuring")
    finally:
        for renderer, _ in renderers.values():
            renderer.close()
    medians = {name: statistics.median(values) for name, values in colour_ms.items()}
    full = medians["none"]
    print(f"shader_cost: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} "
          f"sequences x {config.n_views} views, fastest of {args.rounds} rounds; colour step, wall ms per view")
    print("| cut | what it cuts | colour ms / view | saved ms / view | saved share |")
    print("|---|---|---|---|---|")
    for name, (what, _) in CUTS.items():
        saved = full - medians[name]
        print(f"| {name} | {what} | {medians[name]:.2f} | {saved:+.2f} | {100 * saved / full:.0f} % |")
    print(machine_line(before, machine()))
    return medians


if __name__ == "__main__":
    main()
