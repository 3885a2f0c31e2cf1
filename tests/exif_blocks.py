"""EXIF blocks for the tests' photos."""

from __future__ import annotations

from PIL import ExifTags, Image


def exif_block(ifd0: dict[int, object], exif_ifd: dict[int, object] | None = None
               ) -> Image.Exif:
    """An EXIF block with the tags ``ifd0`` (Make, Model, Orientation) and, in its Exif
    sub-IFD, ``exif_ifd`` (FocalLength, FocalLengthIn35mmFilm, ...); values of None are
    left out. The sub-IFD goes in as a dict under its pointer tag: Pillow 9.5 (the oldest
    the ranges admit) drops the values set through ``Exif.get_ifd(...)[tag]`` when it
    writes the block, and every later Pillow keeps both."""
    exif = Image.Exif()
    for tag, value in ifd0.items():
        if value is not None:
            exif[tag] = value
    sub = {tag: value for tag, value in (exif_ifd or {}).items() if value is not None}
    if sub:
        exif[ExifTags.IFD.Exif] = sub
    return exif
