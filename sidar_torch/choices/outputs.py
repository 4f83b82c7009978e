"""The optional outputs' table: every floor's view of each optional per-view output, one row each.

Like :mod:`sidar_torch.choices.render`, it sits under ``config`` and ``render`` (both follow its rows)
and imports nothing of the package.
"""

from dataclasses import dataclass, field

__all__ = ["OUTPUTS", "OptionalOutput", "drawn_outputs"]


@dataclass(frozen=True)
class OptionalOutput:
    """An optional per-view image output, as every floor sees it: one row of :data:`OUTPUTS`.

    Attributes:
        name: its name everywhere: the sample key (``sample.KEYS``), the ``SampleArrays`` field, the key of
            ``RenderedSequence.outputs`` and of ``RenderSettings.outputs``.
        switch: the boolean config field that turns it on.
        channels: values per pixel: 1 (an ``(H, W)`` array per view) or ``C`` (an ``(H, W, C)`` array; 3 of
            uint8 are sRGB).
        entry: its export file per view (``{v}`` the view's number).
        description: what ``export.json`` says of its files.
        view_pixel_bytes: memory it adds per view and pixel (``config.memory``: its uint8 array and
            float32 tensor; 0 where the measured per-view figure already counts it).
        target_pixel_bytes: bytes per pixel and sample of a render target of its own (the colour pass's
            second output), 0 for none.
        view_effects: the view effects (background, exposure, noise, JPEG: ``sidar_torch.sample.effects``) apply
            to it as to the views, with the same draws (an image of the view); false: it is left as drawn.
        dtype: ``"uint8"`` (8-bit levels, a float tensor of ``level / 255`` in the sample, a PNG file) or
            ``"float32"`` (values with units, the same float32 tensor, a ``.npy`` file).
        producer: how it is made: for a drawn output, the renderer's pass that draws it (a key of
            ``render.renderer.OUTPUT_PASSES``); for a computed one, the CPU step after read-back that computes
            it from ``computed_from`` (a key of ``sample.COMPUTATIONS``, timed under this name).
        computed_from: None for an output the renderer draws; else the drawn output it is computed from
            on the CPU after rendering (``sample.render_arrays``), which is then drawn whether or not it
            is asked for itself.
        lens_resample: a lens may resample it (``sample.lens_views.render_through_lens`` moves its pixels as the
            view's); false: values of a pinhole camera that resampling would make wrong, refused with a
            lens (``config.validation``).
        min_image_side: the fewest pixels each side of the image must have for it (its producer reads
            that many pixel centres around each point).
        values: the dtype and range of its sample tensor, as ``sample.KEYS`` says them.
        meaning: what its values are, with units and frames: its ``sample.KEYS`` row's meaning.
    """

    name: str
    switch: str
    channels: int
    entry: str
    description: str
    view_pixel_bytes: int = 0
    target_pixel_bytes: int = 0
    view_effects: bool = False
    dtype: str = "uint8"
    producer: str = field(kw_only=True)
    computed_from: str | None = None
    lens_resample: bool = True
    min_image_side: int = 1
    values: str = field(kw_only=True)
    meaning: str = field(kw_only=True)


OUTPUTS = {row.name: row for row in (
    OptionalOutput(
        "opacities", "opacity_output", 1, "{v}-o.png",
        "<i>-o.png: 255 x the fraction of the painting hidden (1 off the painting)",
        producer="opacity", values="float32 in [0, 1], multiples of 1/255",
        meaning="the fraction of the painting hidden at each pixel, a soft mask: 1 off the painting and behind "
                "opaque occluders, 0 where the painting is seen unobstructed, 1 - prod_k (1 - a_k) where "
                "transparent occluders k cover it, a_k the opacity the view blends them with (material alpha "
                "raised by Fresnel towards grazing views; their highlights are left out). Every visible occluder "
                "counts, whatever mask_min_opacity is"),
    OptionalOutput(
        "shadow_masks", "shadow_mask_output", 1, "{v}-s.png",
        "<i>-s.png: 255 x the fraction of the direct light on the visible painting that occluders block "
        "(0 off the painting and where it is hidden)", view_pixel_bytes=5,
        producer="shadow_fraction", values="float32 in [0, 1], multiples of 1/255",
        meaning="the fraction of the direct light falling on the visible painting that occluders block: each "
                "light weighted by its irradiance there (luminance; a transparent occluder's coloured shadow "
                "counts by its luminance); 0 exactly where no occluder blocks any light (any blocked light gives at "
                "least 1/255), off the painting and where the painting is hidden (masks); ambient light counts for "
                "nothing"),
    OptionalOutput(
        "shadow_free", "shadow_free_output", 3, "{v}-f.png",
        "<i>-f.png: the view with no light blocked (the target of shadow removal)",
        view_pixel_bytes=15, target_pixel_bytes=4, view_effects=True,
        producer="unblocked_colour", values="float32 in [0, 1], multiples of 1/255",
        meaning="each view from the same scene (lights, occluders, cameras, view effects and noise) with no light "
                "blocked: the target of shadow removal; equal to images wherever no shadow falls"),
    OptionalOutput(
        "depth", "depth_output", 1, "{v}-d.npy",
        "<i>-d.npy: float32 (H, W), the distance along the camera's z axis to the painting or an occluder, "
        "painting units (inf where neither is hit)", view_pixel_bytes=8, target_pixel_bytes=8, dtype="float32",
        producer="camera_depth", lens_resample=False, values="float32, painting units",
        meaning="the distance along the view's camera z axis (R X + t's third coordinate) to the nearest surface the "
                "masks count (the painting, or an occluder at least mask_min_opacity opaque) at each pixel centre, "
                "inf where none is hit; sidar_torch.flow turns it into dense correspondence"),
    OptionalOutput(
        "flow_to_reference", "flow_output", 2, "{v}-flow.npy",
        "<i>-flow.npy: float32 (H, W, 2), where each pixel of view i lands in view 0 minus the pixel, "
        "(du, dv) in pixels; NaN where that is not a seen correspondence (sidar_torch.flow)",
        view_pixel_bytes=24, target_pixel_bytes=8, dtype="float32",
        producer="flow", computed_from="depth", lens_resample=False, min_image_side=2, values="float32, pixels",
        meaning="where each pixel of the view lands in view 0 minus the pixel, (du, dv): sidar_torch.flow(sample, i, 0) "
                "of every view i, NaN where it is not valid (view i sees nothing there, or view 0 does not see the "
                "point); on the painting H[i, 0]'s mapping, on occluders of a static scene their parallax"),
    OptionalOutput(
        "normals", "normals_output", 3, "{v}-n.npy",
        "<i>-n.npy: float32 (H, W, 3), the unit surface normal in the camera's frame (x right, y down, z forward) "
        "of the painting or an occluder, facing the camera (0 where neither is hit)",
        view_pixel_bytes=24, target_pixel_bytes=20, dtype="float32",
        producer="camera_normals", lens_resample=False, values="float32 in [-1, 1], unit vectors",
        meaning="the unit surface normal, in the view's camera frame (x right, y down, z forward: R n for a world "
                "normal n), of the nearest surface the masks count (the painting, or an occluder at least "
                "mask_min_opacity opaque) at each pixel centre, facing the camera (interpolated across an "
                "occluder's smooth faces; on the painting R[:, 2]), 0 where none is hit"),
)}
"""The optional outputs, by name (``flow_to_reference``'s memory counts the depth it is computed from;
opacities' memory is in the measured per-view figure, ``config.memory``). Adding one: a row here, its
switch in ``config/fields.py`` and its producer: the pass or render target that draws it (a row of
``render.renderer.OUTPUT_PASSES``) or the computation from another output (a row of
``sample.COMPUTATIONS``) (``docs/architecture.md``). Its sample key (``sample.KEYS``), its ``SampleArrays``
field, memory, the manifest, export, the reader, Ray, the render settings, the renderer's and the sample's
steps and the config's checks follow the row; no code outside these tables branches on an output's name."""


def drawn_outputs(asked: frozenset[str] | set[str]) -> frozenset[str]:
    """The outputs the renderer draws for the outputs ``asked`` for (names of :data:`OUTPUTS`): those it
    draws itself, and the ones the computed outputs are computed from."""
    return frozenset(OUTPUTS[name].computed_from or name for name in asked)
