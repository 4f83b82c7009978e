"""Where paintings come from: decoding images into paintings (:mod:`.decode`), the painting sources
(:mod:`.sources`) and the built-in procedural paintings (:mod:`.procedural`). ``docs/paintings.md``
says what each source accepts, how bad and large images are handled, and why.
"""

from .decode import (CROP_MODES, MAX_IMAGE_PIXELS, ImageTooLargeError, PaintingSize, array_to_uint8, fit_painting,
                     load_image, tensor_to_uint8)
from .sources import (IMAGE_EXTENSIONS, BadImageWarning, DatasetPaintings, ImageFiles, ImageList, PaintingSource,
                      ProceduralPaintings, TensorPaintings, make_source)

__all__ = ["CROP_MODES", "IMAGE_EXTENSIONS", "MAX_IMAGE_PIXELS", "BadImageWarning", "DatasetPaintings", "ImageFiles",
           "ImageList", "ImageTooLargeError", "PaintingSize", "PaintingSource", "ProceduralPaintings",
           "TensorPaintings", "array_to_uint8", "fit_painting", "load_image", "make_source", "tensor_to_uint8"]
