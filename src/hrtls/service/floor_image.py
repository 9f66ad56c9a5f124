"""Checks of an uploaded floor-plan image (decoded by Pillow, never trusted by its name)."""

from __future__ import annotations

import io
from typing import Any

from fastapi import HTTPException

IMAGE_TYPES = {"image/png": "PNG", "image/jpeg": "JPEG"}
"""Accepted media types and the Pillow format each must decode as."""
MAX_SIDE_PX = 8192
"""Largest width or height accepted (a larger image is refused before it is decoded)."""


def check_floor_image(data: bytes, media_type: str) -> dict[str, Any]:
    """``media_type``, ``width_px`` and ``height_px`` of a PNG or JPEG; HTTP errors otherwise.

    415 for another media type, 422 when the bytes are not a whole image of that type or it is
    larger than ``MAX_SIDE_PX`` on a side.
    """
    from PIL import Image, UnidentifiedImageError

    if media_type not in IMAGE_TYPES:
        raise HTTPException(415, f"Content-Type {media_type or '(none)'!r}: a floor image is "
                                 f"one of {', '.join(IMAGE_TYPES)}")
    if not data:
        raise HTTPException(422, "empty body: the image bytes expected")
    try:
        with Image.open(io.BytesIO(data)) as im:
            fmt, (width, height) = im.format, im.size
            if fmt != IMAGE_TYPES[media_type]:
                raise HTTPException(422, f"the body is {fmt or 'not an image'}, the "
                                         f"Content-Type says {media_type}")
            if max(width, height) > MAX_SIDE_PX:
                raise HTTPException(422, f"image of {width} x {height} px: at most "
                                         f"{MAX_SIDE_PX} px a side")
            im.load()  # decodes every pixel: a truncated or corrupt file fails here
    except (UnidentifiedImageError, Image.DecompressionBombError, OSError, SyntaxError,
            ValueError) as exc:
        raise HTTPException(422, f"not a readable {media_type} image ({exc})") from None
    return {"media_type": media_type, "width_px": int(width), "height_px": int(height)}
