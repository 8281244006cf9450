"""`kisscal init`: folders and a commented session.toml that validates once filled in."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from kisscal import session
from kisscal.errors import KisscalError
from kisscal.io.config import load_toml
from kisscal.io.summary import summarise
from kisscal.session.init import init_session


def test_template_is_commented_and_refuses_until_filled(tmp_path: Path) -> None:
    path = init_session(tmp_path / "lab", n_cameras=3, preset="modern")
    text = path.read_text()
    assert text.count("FILL IN") == 5 and text.count("[[cameras]]") >= 3
    comments = sum(line.lstrip().startswith("#") for line in text.splitlines())
    assert comments > 40  # every key is explained
    for folder in ("grid/cam3", "rods/cam1", "trials/walk01/cam2"):
        assert (tmp_path / "lab" / folder).is_dir()
    blanks = r"still to fill in \(empty\): rods\.rod\[0\]\.points_mm"
    with pytest.raises(KisscalError, match=blanks):
        session.validate(tmp_path / "lab")
    with pytest.raises(KisscalError, match="never overwrites"):
        init_session(tmp_path / "lab", n_cameras=3)


def test_filled_template_validates(small_session: Path, tmp_path: Path) -> None:
    new = tmp_path / "lab"
    path = init_session(new, n_cameras=6, preset="kiss")
    for folder in ("grid", "rods", "trials/walk01"):
        for cam in [f"cam{i}" for i in range(1, 7)]:
            for frame in sorted((small_session / folder / cam).glob("*.png")):
                shutil.copy(frame, new / folder / cam / frame.name)
    rods = iter(load_toml(small_session / "session.toml")["rods"]["rod"])
    filled = re.sub(
        r"points_mm = \[\]\s*# FILL IN[^\n]*",
        lambda _m: f"points_mm = {next(rods)['points_mm']}",
        path.read_text(),
    )
    path.write_text(filled)
    assert session.validate(new) == []


@pytest.mark.slow
def test_a_four_camera_lab_by_the_docs_alone(tmp_path: Path) -> None:
    """docs/your-lab.md, steps 1-7, as a newcomer types them: `kisscal init --cameras 4
    --preset modern`, the images copied in, the rods' survey filled in, `kisscal validate`,
    `kisscal run`; trajectories come out for every marker."""
    from kisscal.cli import main

    lab = session.synthesise(
        tmp_path / "lab-images",
        preset="modern",
        n_cameras=4,
        fields=40,
        walking5=False,
        trials=("walk01",),  # the one trial the newcomer copies in
    )
    new = tmp_path / "lab" / "2026-11-21"

    def kisscal(*args: str) -> int:
        with pytest.raises(SystemExit) as done:
            main(list(args))
        return int(done.value.code or 0)

    assert kisscal("init", str(new), "--cameras", "4", "--preset", "modern") == 0
    for folder in ("grid", "rods", "trials/walk01"):
        for cam in [f"cam{i}" for i in range(1, 5)]:
            for frame in sorted((lab / folder / cam).glob("*.png")):
                shutil.copy(frame, new / folder / cam / frame.name)
    rods = iter(load_toml(lab / "session.toml")["rods"]["rod"])
    toml = new / "session.toml"
    toml.write_text(
        re.sub(
            r"points_mm = \[\]\s*# FILL IN[^\n]*",
            lambda _m: f"points_mm = {next(rods)['points_mm']}",
            toml.read_text(),
        )
    )
    assert kisscal("validate", str(new)) == 0
    assert kisscal("run", str(new)) == 0
    tracking = summarise(new)["trials"]["walk01"]
    assert tracking["trajectories"] >= 15
    assert (new / "out" / "trials" / "walk01" / "trajectories.c3d").is_file()
    assert (new / "out" / "report.html").is_file()
