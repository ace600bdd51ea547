"""Reading a scene or URDF file as text, under the size limit, with named errors."""

from __future__ import annotations

from pathlib import Path

from casmbd.errors import LimitError, SceneError
from casmbd.limits import MAX_SCENE_BYTES, format_bytes

__all__ = ["read_text"]


def read_text(path: Path, what: str) -> str:
    """The text of ``path`` (UTF-8, a BOM ignored), refused above :data:`MAX_SCENE_BYTES`.

    Raises
    ------
    LimitError
        The file is larger than the limit (checked before reading).
    SceneError
        The file is missing or unreadable; the message names ``what`` file and the path.
    """
    try:
        size = path.stat().st_size if path.is_file() else 0
        if size > MAX_SCENE_BYTES:
            raise LimitError(f"{what} file '{path}': {format_bytes(size)} exceeds the limit of "
                             f"{format_bytes(MAX_SCENE_BYTES)} (casmbd.limits.MAX_SCENE_BYTES)")
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise SceneError(f"{what} file '{path}' not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{what} file '{path}' cannot be read: {exc}") from None
