"""Viewer benchmark (prints figures): first pipeline run, slider changes, and frame time.

    python tests/benchmarks/bench_viewer.py            # off-screen (EGL), no Qt
    xvfb-run -a -s "-screen 0 1280x1024x24" python tests/benchmarks/bench_viewer.py --window

Off-screen, for the demo and the Kennecott table (when present): the first
full pipeline of the selected geozone (no stage cache, then the same input
opened again on a filled cache), the time from a parameter change to the
first updated picture and to every bench redone, and the frame time of a
rotation. ``--window`` drives the Qt window the same way.

Targets (issues 6 and 14): under 0.5 s from a slider change to the updated
contour, all benches redone within 3 s on the demo, under 50 ms a frame.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
warnings.simplefilter("ignore")
os.environ.setdefault("BGM_CACHE_DIR", tempfile.mkdtemp(prefix="bgm-bench-cache-"))  # never the user's cache

import numpy as np  # noqa: E402
from kennecott_data import KENNECOTT  # noqa: E402

from bgm_viewer.builders import build_scene, refresh_scene  # noqa: E402
from bgm_viewer.model import ViewerModel, compute  # noqa: E402
from bgm_viewer.screenshot import plotter_for  # noqa: E402

#: Input, geozone and bench pair to select (Kennecott: a geozone drilled on the selected benches).
INPUTS = {"demo": (None, "g1", 0), "kennecott": (KENNECOTT, "3310", 2)}
#: Parameter changes timed: a snake parameter (its component is previewed first) and a boundary one.
CHANGES = (("gvf_mu", (0.1, 0.3, 0.2)), ("entropy_threshold", (0.4, 0.6, 0.5)))


def timed_run(model: ViewerModel, step: str) -> dict:
    """Run from ``step``; seconds to the first picture, to every bench redone, and to the end."""
    t0 = time.perf_counter()
    out: dict = {}
    for msg, _frac, res in compute(model.inputs(), model.result, step):
        now = time.perf_counter() - t0
        out.setdefault("first", now)
        if msg.startswith("contours of bench") or msg == "contours of the bench pair":
            out["benches"] = now
        model.set_result(res)
    out["done"] = time.perf_counter() - t0
    return out


def bench_pipeline(name: str, source, geozone: str, bench: int) -> ViewerModel:
    model = ViewerModel(source, cache=False)
    model.select(geozone, bench, 0)
    t = timed_run(model, "contours")
    print(
        f"{name}: first full pipeline of {geozone} (no cache): first picture {t['first']:.2f} s, "
        f"all benches {t['benches']:.2f} s, done {t['done']:.2f} s"
    )
    for k, v in model.result.timings.items():
        if not k.startswith("contours of bench"):
            print(f"  {k:<20s} {v:.3f} s")
    for attempt in ("fills", "reads"):
        again = ViewerModel(source)  # on the stage cache
        again.select(geozone, bench, 0)
        t = timed_run(again, "contours")
        print(f"{name}: opened on a stage cache it {attempt}: first picture {t['first']:.2f} s, done {t['done']:.2f} s")
    for param, values in CHANGES:
        runs = []
        for value in values:
            runs.append(timed_run(model, model.set_param(param, value)))
        first = [r["first"] for r in runs]
        benches = [r["benches"] for r in runs]
        done = [r["done"] for r in runs]
        print(
            f"{name}: {param} change -> first picture median {np.median(first):.2f} s, "
            f"all benches redone {np.median(benches):.2f} s, done {np.median(done):.2f} s "
            f"({', '.join(f'{v:.2f}' for v in done)})"
        )
    return model


def bench_offscreen(model: ViewerModel, n_frames: int = 36) -> None:
    scene = build_scene(
        model.holes,
        model.result,
        model.selection,
        visible=["blastholes", "contours", "snake", "trajectories", "surfaces"],
    )
    plotter, renderer = plotter_for(scene, window_size=(1280, 960), camera="iso")
    plotter.render()
    # slider change -> contour on screen (snake-stage parameter: its component is previewed first)
    times = []
    for value in (0.1, 0.3, 0.15):
        step = model.set_param("gvf_mu", value)
        t = time.perf_counter()
        steps = compute(model.inputs(), model.result, step)
        _msg, _f, res = next(steps)
        steps.close()
        previous = model.result
        model.set_result(res)
        refresh_scene(scene, model.holes, res, model.selection, previous=previous)
        plotter.ren_win.Render()
        times.append(time.perf_counter() - t)
    print(
        f"slider change -> updated contour on screen: median {np.median(times) * 1000:.0f} ms "
        f"(target < 500 ms) {['%.0f' % (x * 1000) for x in times]}"
    )
    cam = plotter.camera
    ft = []
    for _ in range(n_frames):
        cam.azimuth += 10
        t = time.perf_counter()
        plotter.ren_win.Render()
        ft.append(time.perf_counter() - t)
    print(
        f"frame time rotating the demo scene: median {np.median(ft) * 1000:.1f} ms, "
        f"max {np.max(ft) * 1000:.1f} ms (target < 50 ms)"
    )
    plotter.close()


def bench_window(name: str, source, geozone: str, bench: int, sliders: bool) -> None:
    """The Qt window on ``source``: first picture, slider changes (``sliders``), rotation with every layer on."""
    from qtpy import QtWidgets

    from bgm_viewer.app import MainWindow
    from bgm_viewer.builders import LAYER_NAMES

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication([])
    model = ViewerModel(source)
    model.select(geozone, bench, 0)
    t0 = time.perf_counter()
    win = MainWindow(model, debounce_ms=0, restore=False)  # no one answers a restore question here
    win.show()
    shown: list[float] = []
    win.resultShown.connect(lambda: shown.append(time.perf_counter()))
    win.wait_idle(900)
    print(
        f"window on {name}: first picture {shown[0] - t0:.2f} s, whole pipeline with "
        f"{len(win.model.result.surfaces)} geozones' surfaces {time.perf_counter() - t0:.2f} s"
    )
    for param, values in CHANGES if sliders else ():
        lat, total = [], []
        for value in values:
            shown.clear()
            t = time.perf_counter()
            win.param_controls[param].slider.setValue(value)
            while not shown:
                app.processEvents()
                time.sleep(0.005)
            lat.append(shown[0] - t)
            win.wait_idle(300)
            total.append(time.perf_counter() - t)
        print(
            f"window on {name}: {param} slider change -> updated contour shown: "
            f"{['%.0f ms' % (x * 1000) for x in lat]}, everything redone: {[f'{x:.1f} s' for x in total]}"
        )
    for layer in LAYER_NAMES:
        win.set_layer_visible(layer, True)
    app.processEvents()
    # Rotate as a user does: a left drag through the VTK interactor, each move
    # handled and painted by Qt before the next.
    iren = win.plotter.iren.interactor
    w, h = win.plotter.window_size
    renders = []
    win.plotter.ren_win.AddObserver("EndEvent", lambda *a: renders.append(1))
    iren.SetEventInformation(w // 2, h // 2, 0, 0)
    iren.InvokeEvent("LeftButtonPressEvent")
    app.processEvents()
    ft = []
    for i in range(1, 37):
        t = time.perf_counter()
        iren.SetEventInformation(w // 2 + 8 * i, h // 2, 0, 0)
        iren.InvokeEvent("MouseMoveEvent")
        app.processEvents()
        ft.append(time.perf_counter() - t)
    iren.InvokeEvent("LeftButtonReleaseEvent")
    app.processEvents()
    print(
        f"window on {name} ({w} x {h} px view, every layer on): frame time rotating with the mouse: "
        f"median {np.median(ft) * 1000:.1f} ms, max {np.max(ft) * 1000:.1f} ms, "
        f"{len(renders)} renders for 36 moves (target < 50 ms)"
    )
    win.model.dirty = False
    win.close()
    sys.stdout.flush()


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--window", action="store_true", help="also drive the Qt window (needs a display)")
    ap.add_argument("--window-only", action="store_true", help="only drive the Qt window")
    args = ap.parse_args()
    found = {k: v for k, v in INPUTS.items() if v[0] is None or Path(v[0]).exists()}
    for name in INPUTS.keys() - found.keys():
        print(f"{name}: not found at {INPUTS[name][0]}; skipped")
    if not args.window_only:
        demo = None
        for name, (source, geozone, bench) in found.items():
            model = bench_pipeline(name, source, geozone, bench)
            demo = demo or model
        bench_offscreen(demo)
    if args.window or args.window_only:
        for name, (source, geozone, bench) in found.items():
            bench_window(name, source, geozone, bench, sliders=name == "demo")
    sys.stdout.flush()
    os._exit(0)  # skip interpreter teardown of VTK/Qt objects
