"""Regenerate the figures the documentation shows, with the commands the pages describe.

Each figure is what a ``fuzzyservo`` command writes, run here into a temporary folder and
copied to ``docs/img/`` at a width of at most ``--width`` pixels (small PNGs that the
repository keeps). Nothing is drawn by hand: a change to a model, a controller or a plot
shows up the next time this runs.

    python docs/gen_figures.py               # every figure (a few minutes: it tunes and calibrates)
    python docs/gen_figures.py bode history  # some of them
    python docs/gen_figures.py --designer    # also the designer's screenshot (Chromium + Playwright)

The designer's screenshot needs ``/usr/bin/chromium`` and the ``[designer]`` and
``playwright`` packages (as ``tests/test_designer_browser.py`` does).
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
IMG = ROOT / "docs" / "img"
CHROMIUM = Path(os.environ.get("FUZZYSERVO_CHROMIUM", "/usr/bin/chromium"))

# name -> (the command's arguments, the file it writes under its --out folder)
FIGURES: dict[str, tuple[list[str], str]] = {
    "seed002_response": (
        ["compare", "dinca_cylinder", "p_k10", "flc1_translated", "flc2_reshaped"],
        "dinca_cylinder_pulses_p_k10+flc1_translated+flc2_reshaped_response.png",
    ),
    "tuning_history": (["tune", "dinca_flc", "--trials", "60", "--workers", "1"], "history.png"),
    "tuning_curve": (["tune", "dinca_flc", "--trials", "60", "--workers", "1"], "curve.png"),
    "calibration_overlay": (
        [
            "calibrate",
            "dinca_cylinder",
            str(ROOT / "examples" / "run_dinca_friction.csv"),
            "--controller",
            "p_k10",
            "--effects",
            "coulomb_friction,stribeck_friction,valve_lag,internal_leakage",
        ],
        "overlay_zoom.png",
    ),
    "bode": (["frequency", "dinca_cylinder", "p_k10"], "bode_dinca_cylinder_p_k10.png"),
}


def _fuzzyservo(args: list[str], out: Path) -> None:
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    cmd = [sys.executable, "-m", "fuzzyservo", *args, "--out", str(out)]
    print("+ fuzzyservo " + " ".join(args), flush=True)
    subprocess.run(cmd, check=True, cwd=out, env=env, stdout=subprocess.DEVNULL)


def _shrink(src: Path, name: str, width: int) -> Path:
    """Copy ``src`` to docs/img/<name>.png, scaled down to ``width`` pixels at most."""
    IMG.mkdir(parents=True, exist_ok=True)
    dst = IMG / f"{name}.png"
    with Image.open(src) as im:
        if im.width > width:
            im = im.resize((width, round(im.height * width / im.width)), Image.Resampling.LANCZOS)
        im.convert("RGB").quantize(colors=128).save(dst, optimize=True)
    print(f"  {dst.relative_to(ROOT)} ({dst.stat().st_size // 1024} kB)")
    return dst


def figures(names: list[str], width: int) -> None:
    with tempfile.TemporaryDirectory(prefix="fuzzyservo_figures_") as tmp:
        done: dict[tuple[str, ...], Path] = {}
        for name in names:
            args, written = FIGURES[name]
            out = done.get(tuple(args))
            if out is None:  # two figures of one command run it once
                out = Path(tmp) / name
                out.mkdir()
                _fuzzyservo(args, out)
                done[tuple(args)] = out
            found = sorted(out.rglob(written))
            if not found:
                raise SystemExit(f"gen_figures: {' '.join(args)} wrote no {written} under {out}")
            _shrink(found[0], name, width)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def designer(width: int) -> None:
    """A screenshot of the designer on seed 002's rig and FLC2, as the browser test takes it."""
    from playwright.sync_api import sync_playwright

    if not CHROMIUM.is_file():
        raise SystemExit(f"gen_figures: no Chromium at {CHROMIUM} (apt-get install chromium)")
    with tempfile.TemporaryDirectory(prefix="fuzzyservo_designer_") as tmp:
        port = _free_port()
        env = dict(
            os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
        )
        cmd = [sys.executable, "-m", "fuzzyservo", "designer", "--port", str(port), "--out", tmp]
        print("+ fuzzyservo designer", flush=True)
        proc = subprocess.Popen(
            cmd, cwd=tmp, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
                page = browser.new_page(viewport={"width": 1420, "height": 1250})
                deadline = time.monotonic() + 180
                while True:
                    try:
                        page.goto(f"http://127.0.0.1:{port}/", timeout=10_000)
                        break
                    except Exception:
                        if time.monotonic() > deadline:
                            raise
                        time.sleep(1)
                page.wait_for_selector("#fs-metrics", timeout=180_000)
                page.wait_for_timeout(2000)
                shot = Path(tmp) / "designer.png"
                page.screenshot(path=str(shot))
                browser.close()
            _shrink(shot, "designer", width)
        finally:
            proc.terminate()
            proc.wait(timeout=30)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "names", nargs="*", help=f"figures to make (default: all): {', '.join(FIGURES)}"
    )
    ap.add_argument("--width", type=int, default=900, help="largest width in pixels (default 900)")
    ap.add_argument("--designer", action="store_true", help="also the designer's screenshot")
    args = ap.parse_args(argv)
    unknown = sorted(set(args.names) - set(FIGURES))
    if unknown:
        ap.error(f"unknown figure(s) {unknown}; choose from {list(FIGURES)}")
    figures(args.names or list(FIGURES), args.width)
    if args.designer:
        designer(args.width)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
