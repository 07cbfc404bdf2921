"""An image's size from its header alone, before any sample is decoded.

:func:`image_header` reads a PNG's IHDR (the 33 bytes after which the image data begins)
or a TIFF's first image file directory (through ``tifffile``, which reads the tags and no
strip or tile), and returns the width, height, bits per sample and channels the file
declares. A reader compares them with what it can hold (:func:`check_pixels`) before it
inflates anything, so a decompression bomb (a 0.5 MB PNG declaring 16384² 16-bit samples,
512 MiB decoded and several times that as floats) is refused in one line naming its
dimensions and the limit. Nothing here decodes image data; every problem is an
:class:`ImageHeaderError` of one line naming the file.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass
from typing import BinaryIO

from glshade.errors import GlshadeError, printable
from glshade.logs import silenced

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: TIFF's first bytes: little-endian ("II") or big-endian ("MM"), classic (42) or BigTIFF
#: (43).
TIFF_SIGNATURES = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
#: Samples a pixel holds, by PNG colour type (a palette image holds one index a pixel).
PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
#: The bit depths PNG allows for each colour type.
PNG_DEPTHS = {0: (1, 2, 4, 8, 16), 2: (8, 16), 3: (1, 2, 4, 8), 4: (8, 16), 6: (8, 16)}
#: The largest width or height PNG allows (2^31 - 1).
PNG_MAX_SIDE = (1 << 31) - 1


class ImageHeaderError(GlshadeError, ValueError):
    """An image whose header is missing, damaged or declares more than a reader holds."""


@dataclass(frozen=True)
class ImageHeader:
    """What an image file declares: ``width`` x ``height`` pixels of ``channels`` samples
    of ``bit_depth`` bits each; ``kind`` is ``"png"`` or ``"tiff"``."""

    kind: str
    width: int
    height: int
    bit_depth: int
    channels: int

    @property
    def pixels(self) -> int:
        return self.width * self.height

    @property
    def decoded_bytes(self) -> int:
        """Bytes of the samples decoded (each sample in whole bytes, as decoders give)."""
        return self.pixels * self.channels * -(-self.bit_depth // 8)

    def describe(self) -> str:
        """``16384 x 16384 pixels, 16-bit, 1 channel``: for messages."""
        plural = "" if self.channels == 1 else "s"
        return (
            f"{self.width} x {self.height} pixels, {self.bit_depth}-bit, "
            f"{self.channels} channel{plural}"
        )


def image_header(path: str | os.PathLike[str], what: str = "image") -> ImageHeader:
    """The header of the PNG or TIFF at ``path`` (recognised by its first bytes, whatever
    its name), read from a regular file without decoding a sample; ``what`` names the
    file's role in messages."""
    from glshade.files import open_regular

    name = printable(os.fspath(path))
    fd = open_regular(path, what)
    with os.fdopen(fd, "rb") as stream:
        return stream_header(stream, f"{what} {name}")


def stream_header(stream: BinaryIO, name: str) -> ImageHeader:
    """The header of the PNG or TIFF ``stream`` (at its start; seekable), ``name``
    naming it in messages. The stream's position afterwards is unspecified."""
    head = stream.read(33)
    if head.startswith(PNG_SIGNATURE):
        return png_header(head, name)
    if head[:4] in TIFF_SIGNATURES:
        stream.seek(0)
        return tiff_header(stream, name)
    raise ImageHeaderError(f"{name}: is neither a PNG nor a TIFF (no PNG or TIFF signature)")


def png_header(head: bytes, name: str) -> ImageHeader:
    """The header in a PNG's first 33 bytes (signature, IHDR and its CRC), checked: the
    IHDR first, its length 13, its CRC right, sides of 1 to 2^31 - 1, a bit depth the
    colour type allows."""
    if len(head) < 33 or not head.startswith(PNG_SIGNATURE):
        raise ImageHeaderError(f"{name}: is not a PNG (no signature and header)")
    if head[8:16] != b"\x00\x00\x00\rIHDR":
        raise ImageHeaderError(f"{name}: is a damaged PNG (its first chunk is not IHDR)")
    if zlib.crc32(head[12:29]) != struct.unpack(">I", head[29:33])[0]:
        raise ImageHeaderError(f"{name}: is a damaged PNG (its IHDR fails its CRC)")
    width, height, bits, colour = struct.unpack(">IIBB", head[16:26])
    if not (1 <= width <= PNG_MAX_SIDE and 1 <= height <= PNG_MAX_SIDE):
        raise ImageHeaderError(
            f"{name}: is a damaged PNG (it declares {width} x {height} pixels; PNG allows "
            f"1 to {PNG_MAX_SIDE} a side)"
        )
    if bits not in PNG_DEPTHS.get(colour, ()):
        raise ImageHeaderError(
            f"{name}: is a damaged PNG (bit depth {bits} with colour type {colour})"
        )
    return ImageHeader("png", width, height, bits, PNG_CHANNELS[colour])


def tiff_header(stream: BinaryIO, name: str) -> ImageHeader:
    """The first page's size of the TIFF ``stream``: its tags only (``tifffile`` reads
    no strip or tile to list them), its log and warnings kept off stderr."""
    import tifffile

    try:
        with silenced("tifffile"), tifffile.TiffFile(stream, name="image.tif") as tif:
            page = tif.pages.first
            width, height = int(page.imagewidth), int(page.imagelength)
            bits, channels = int(page.bitspersample), int(page.samplesperpixel)
    except (tifffile.TiffFileError, OSError, ValueError, TypeError, LookupError) as exc:
        detail = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise ImageHeaderError(f"{name}: is a damaged TIFF ({detail})") from None
    except (ArithmeticError, EOFError, MemoryError, struct.error) as exc:
        raise ImageHeaderError(f"{name}: is a damaged TIFF ({type(exc).__name__})") from None
    if min(width, height, bits, channels) < 1:
        raise ImageHeaderError(
            f"{name}: is a damaged TIFF (it declares {width} x {height} pixels of "
            f"{channels} x {bits} bits)"
        )
    return ImageHeader("tiff", width, height, bits, channels)


def check_pixels(header: ImageHeader, max_pixels: int, name: str, why: str = "") -> None:
    """Refuse, in one line naming the dimensions and the limit, an image of more than
    ``max_pixels`` pixels (``why``: where the limit comes from, for the message)."""
    if header.pixels > max_pixels:
        because = f" ({why})" if why else ""
        raise ImageHeaderError(
            f"{name}: declares {header.describe()} = {header.pixels} pixels, more than the "
            f"{max_pixels} allowed{because}; nothing was decoded"
        )
