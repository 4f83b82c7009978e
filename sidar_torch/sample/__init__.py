"""The sample floor: the contract every consumer reads (:mod:`.contract`: ``KEYS``, ``SampleArrays``), the
one path that assembles a sample from the renderer's output (:mod:`.assembly`: ``render_arrays``), and the
steps around the renderer: a lens's canvas and resampling (:mod:`.lens_views`: the renderer bends the views in
GL), then after read-back the view effects (:mod:`.effects`) and flow from depth (:mod:`.depth_flow`, and
:mod:`.correspondence` for a sample's views); a renderer's warm-up (:mod:`.warm_up`)."""

from .assembly import COMPUTATIONS, batch_homographies, render_arrays, render_sample, sequence_homographies
from .contract import (FLOAT_OUTPUTS, GEOMETRY_DTYPES, KEYS, LENS_KEYS, PIXEL_KEYS, SampleArrays, SampleKey, float_tensor,
                       present_keys, stack_arrays, stack_samples)

__all__ = ["COMPUTATIONS", "FLOAT_OUTPUTS", "GEOMETRY_DTYPES", "KEYS", "LENS_KEYS", "PIXEL_KEYS", "SampleArrays", "SampleKey",
           "batch_homographies", "float_tensor", "present_keys", "render_arrays", "render_sample", "sequence_homographies",
           "stack_arrays", "stack_samples"]
