"""Viewer benchmark (prints figures): slider change -> updated contour on screen, and frame time.

    python tests/benchmarks/bench_viewer.py            # off-screen (EGL), no Qt
    xvfb-run -a -s "-screen 0 1280x1024x24" python tests/benchmarks/bench_viewer.py --window

Targets (issue 6): under 0.5 s from a slider change to the updated contour for a
typical component, under 50 ms a frame when rotating the demo scene.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
warnings.simplefilter("ignore")

import numpy as np  # noqa: E402

from bgm_viewer.builders import build_scene, refresh_scene  # noqa: E402
from bgm_viewer.model import ViewerModel, compute  # noqa: E402
from bgm_viewer.screenshot import plotter_for  # noqa: E402


def bench_offscreen(n_frames: int = 36) -> dict:
    t0 = time.perf_counter()
    model = ViewerModel(None)  # the demo
    model.select("g1", 0, 0)
    model.run()
    print(f"demo pipeline (all stages, {model.holes.n_benches} benches): {time.perf_counter() - t0:.2f} s")
    for k, v in model.result.timings.items():
        print(f"  {k:<20s} {v:.3f} s")
    scene = build_scene(
        model.holes,
        model.result,
        model.selection,
        visible=["blastholes", "contours", "snake", "trajectories", "surfaces"],
    )
    plotter, renderer = plotter_for(scene, window_size=(1280, 960), camera="iso")
    plotter.render()
    # slider change -> contour on screen (snake-stage parameter: fast path)
    times = []
    for value in (0.1, 0.3, 0.15):
        model.set_param("gvf_mu", value)
        t = time.perf_counter()
        steps = compute(model.inputs(), model.result, "snake")
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
    # frame time while rotating
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
    return {"slider_s": float(np.median(times)), "frame_s": float(np.median(ft))}


def bench_window() -> None:
    from qtpy import QtWidgets

    from bgm_viewer.app import MainWindow

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication([])
    model = ViewerModel(None)
    model.select("g1", 0, 0)
    win = MainWindow(model, debounce_ms=0)
    win.show()
    win.wait_idle(120)
    for name, values in (("gvf_mu", (0.1, 0.3, 0.15)), ("entropy_threshold", (0.4, 0.6, 0.5))):
        lat = []
        for value in values:
            shown = []
            win.resultShown.connect(lambda shown=shown: shown.append(time.perf_counter()))
            t = time.perf_counter()
            win.param_controls[name].field.setValue(value)
            while not shown:
                app.processEvents()
                time.sleep(0.005)
            lat.append(shown[0] - t)
            win.wait_idle(120)
        print(f"window: {name} slider change -> updated contour shown: {['%.0f ms' % (x * 1000) for x in lat]}")
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
        f"window ({w} x {h} px view): frame time rotating with the mouse: median {np.median(ft) * 1000:.1f} ms, "
        f"max {np.max(ft) * 1000:.1f} ms, {len(renders)} renders for 36 moves (target < 50 ms)"
    )
    win.model.dirty = False
    win.close()
    sys.stdout.flush()
    os._exit(0)  # skip interpreter teardown of VTK/Qt objects


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--window", action="store_true", help="also drive the Qt window (needs a display)")
    args = ap.parse_args()
    bench_offscreen()
    if args.window:
        bench_window()
