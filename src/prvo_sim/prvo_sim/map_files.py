"""Map files in the format of ROS map_server: an image whose pixels become occupancy cells.

A map's YAML names the image and how to read it (`mode`, `negate`, `occupied_thresh`,
`free_thresh`); `prvo_sim.scenario` checks it. The pixels are read as map_server reads them:
grey levels (a colour image by its luminance), the image's top row the grid's last row.
"""

import os
import stat
import warnings

import numpy as np
from PIL import Image, UnidentifiedImageError

from prvo_planner.maps import FREE, OCCUPIED, UNKNOWN

MODES = ('trinary', 'scale', 'raw')
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.25


def check_regular_file(path):
    """Raise OSError unless PATH is a regular file (or a link to one), with the reason.

    Reading a FIFO would wait for a writer, reading a device might never end: neither is read.
    """
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        kind = ('a FIFO' if stat.S_ISFIFO(mode) else 'a directory' if stat.S_ISDIR(mode)
                else 'a socket' if stat.S_ISSOCK(mode) else 'a device')
        raise OSError(f'not a regular file ({kind})')


def read_image(path, max_pixels):
    """Return (grey levels (H, W) uint8, alpha (H, W) uint8) of the PGM or PNG image at PATH.

    A colour image is read by its luminance (Pillow's ITU-R 601-2 luma), an image without
    transparency as opaque. The size the image's header declares is checked before its pixels
    are decoded: more than MAX_PIXELS is refused. Raises OSError (unreadable, not an image, too
    large, not a regular file) with the reason.
    """
    try:
        check_regular_file(path)
        with warnings.catch_warnings():
            # Pillow warns of a possible decompression bomb above its own limit; the bound that
            # applies here is MAX_PIXELS, checked below before decoding.
            warnings.simplefilter('ignore', Image.DecompressionBombWarning)
            image = Image.open(path)
        with image:
            width, height = image.size
            if width * height > max_pixels:
                raise OSError(f'its header declares {width} x {height}, more than '
                              f'{max_pixels:.3g} pixels')
            image.load()
            grey_alpha = image.convert('LA')
    except Image.DecompressionBombError as error:
        # Pillow refuses a header declaring over twice its limit before the size is seen here.
        raise OSError(f'its header declares more than {max_pixels:.3g} pixels ({error})') from None
    except (UnidentifiedImageError, ValueError, SyntaxError, EOFError) as error:
        # Pillow's readers report a malformed file by any of these.
        raise OSError(f'not an image Pillow reads: {error}') from None
    levels = np.asarray(grey_alpha, dtype=np.uint8)
    return levels[..., 0], levels[..., 1]


def cells_from_image(levels, alpha, mode, negate, occupied_thresh, free_thresh):
    """Return the (H, W) int8 occupancy cells of an image, its bottom row first.

    LEVELS, ALPHA (H, W) uint8, the image's rows from the top. With shade = level / 255 and
    occupancy p = shade if NEGATE else 1 - shade: 'trinary' gives 100 where p >
    OCCUPIED_THRESH, 0 where p < FREE_THRESH, -1 between; 'scale' the same, -1 for a pixel not
    wholly opaque, and between the thresholds round(100 (p - FREE_THRESH) / (OCCUPIED_THRESH -
    FREE_THRESH)); 'raw' the level itself where it is at most 100, else -1 (NEGATE unused).
    """
    levels = np.asarray(levels)
    if mode == 'raw':
        cells = np.where(levels <= OCCUPIED, levels, UNKNOWN)
    else:
        shade = levels / 255.0
        occupancy = shade if negate else 1.0 - shade
        cells = np.full(levels.shape, UNKNOWN, dtype=np.int16)
        if mode == 'scale':
            span = occupied_thresh - free_thresh
            between = (occupancy >= free_thresh) & (occupancy <= occupied_thresh)
            if span > 0.0:
                cells[between] = np.rint((occupancy[between] - free_thresh) / span * 100.0)
        cells[occupancy > occupied_thresh] = OCCUPIED
        cells[occupancy < free_thresh] = FREE
        if mode == 'scale':
            cells[np.asarray(alpha) != 255] = UNKNOWN
    return np.ascontiguousarray(cells[::-1]).astype(np.int8)
