"""What a publisher's PDF check reads from a figure PDF, parsed with the standard library: the
page size (``/MediaBox``, in points of 1/72 in), the fonts' subtypes (``/Subtype /Type3`` is what
IEEE PDF eXpress rejects; matplotlib's Type 42 fonts show as ``/TrueType`` or ``/CIDFontType2``)
and the sizes of the text drawn (every ``Tf`` operator of the page's content streams, in pt)."""
from __future__ import annotations

import re
import zlib
from dataclasses import dataclass
from pathlib import Path

_STREAM = re.compile(rb"<<(?P<dict>(?:(?!>>\s*stream).)*?)>>\s*stream\r?\n(?P<data>.*?)endstream",
                     re.S)
_MEDIABOX = re.compile(rb"/MediaBox\s*\[\s*([-\d.\s]+)\]")
_FONT_SUBTYPE = re.compile(rb"/Type\s*/Font\b[^>]*?/Subtype\s*/(\w+)|"
                           rb"/Subtype\s*/(\w+)[^>]*?/Type\s*/Font\b", re.S)
_TEXT_SIZE = re.compile(rb"/[\w.+-]+\s+(-?[\d.]+)\s+Tf\b")


@dataclass(frozen=True)
class PdfPage:
    width_in: float
    height_in: float
    font_subtypes: frozenset[str]
    text_sizes_pt: tuple[float, ...]


def read_pdf_page(path: Path) -> PdfPage:
    """The one page of a figure PDF (as matplotlib writes it: uncompressed objects, Flate-
    compressed content streams)."""
    raw = Path(path).read_bytes()
    x0, y0, x1, y1 = map(float, _MEDIABOX.search(raw).group(1).split())
    subtypes = frozenset(a or b for a, b in
                         ((m.group(1), m.group(2)) for m in _FONT_SUBTYPE.finditer(raw)))
    sizes = []
    for stream in _STREAM.finditer(raw):
        data = stream.group("data")
        if b"/FlateDecode" in stream.group("dict"):
            try:
                data = zlib.decompress(data)
            except zlib.error:
                continue
        sizes += [float(size) for size in _TEXT_SIZE.findall(data)]
    return PdfPage((x1 - x0) / 72, (y1 - y0) / 72,
                   frozenset(s.decode() for s in subtypes), tuple(sizes))
