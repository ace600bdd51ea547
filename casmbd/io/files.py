"""Reading a scene or URDF file as text, under the size limit, with named errors."""

from __future__ import annotations

from pathlib import Path

from casmbd.errors import SceneError
from casmbd.limits import MAX_SCENE_BYTES, read_bounded

__all__ = ["read_text"]


def read_text(path: Path, what: str) -> str:
    """The text of ``path`` (UTF-8, a BOM ignored), refused above :data:`MAX_SCENE_BYTES`.

    The file must be a regular file (checked with ``os.stat`` before it is opened: a FIFO or
    a device such as ``/dev/zero`` is refused, never read) and at most
    :data:`MAX_SCENE_BYTES` long; at most that many bytes plus one are read
    (:func:`casmbd.limits.read_bounded`).

    Raises
    ------
    LimitError
        The file is larger than the limit (checked before reading).
    SceneError
        The file is missing, not a regular file or unreadable; the message names ``what``
        file and the path.
    """
    data = read_bounded(path, what, MAX_SCENE_BYTES, SceneError)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{what} file '{path}' cannot be read: {exc}") from None
