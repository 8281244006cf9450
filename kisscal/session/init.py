"""``kisscal init``: a new session's folders and a fully commented ``session.toml``."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from string import Template

from kisscal.errors import InputError
from kisscal.io.files import write_text


@dataclass(frozen=True)
class Preset:
    """What ``kisscal init --preset`` assumes of a lab's cameras."""

    rate_hz: float
    size_px: tuple[int, int] | None


PRESETS: dict[str, Preset] = {
    # KISS-like: 752 x 291 interlaced video fields at 50 Hz
    "kiss": Preset(50.0, (752, 291)),
    # a modern optical system: square-pixel sensors, 100 Hz; size taken from the images
    "modern": Preset(100.0, None),
    # webcams: 30 Hz, size taken from the images
    "lowcost": Preset(30.0, None),
}


def init_session(root: Path, n_cameras: int, preset: str = "modern") -> Path:
    """Create ``root`` with one image folder per camera and a commented ``session.toml``.

    Returns the path of ``session.toml``. A folder that already holds a session is refused
    (nothing is overwritten).
    """
    root = Path(root)
    if preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r}; choose one of {', '.join(PRESETS)}")
    if not 1 <= n_cameras <= 64:
        raise InputError(f"--cameras must be between 1 and 64, got {n_cameras}")
    if (root / "session.toml").exists():
        raise InputError(f"{root / 'session.toml'} exists; init never overwrites a session")
    cameras = [f"cam{i}" for i in range(1, n_cameras + 1)]
    for folder in ("grid", "rods", "trials/walk01"):
        for cam in cameras:
            (root / folder / cam).mkdir(parents=True, exist_ok=True)
    text = session_template(root.name, root, cameras, PRESETS[preset])
    path = root / "session.toml"
    write_text(path, text)
    return path


def session_template(name: str, folder: Path, cameras: list[str], preset: Preset) -> str:
    """The commented ``session.toml`` of a new session (``kisscal/data/session_template.toml``)."""
    template = resources.files("kisscal.data").joinpath("session_template.toml").read_text()
    size = (
        f"size = [{preset.size_px[0]}, {preset.size_px[1]}]"
        if preset.size_px
        else "# size = [width, height]"
    )
    entries = "\n".join(f'[[cameras]]\nid = "{c}"\n{size}\n' for c in cameras)
    return Template(template).substitute(
        name=name, folder=folder, rate_hz=f"{preset.rate_hz:g}", cameras=entries
    )
