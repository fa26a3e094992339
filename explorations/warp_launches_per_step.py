"""Non-empty kernel launches in one MuJoCo Warp step of the default pair, by mujoco-warp release
(a finding, never asserted; docs/gpu.md "What one step launches").

    python explorations/warp_launches_per_step.py

On a GPU a step is a chain of small kernels, so its time at small world counts follows their
number.  Counted on Warp's CPU device, every launch recorded and not run, the solver's loop
unrolled (at the model's iterations, then at 1: the rest of the step).  It writes the pair's
affine-servo model to /tmp/pair_affine.xml with the installed undulate, then reads it back, so the
count can be repeated in another environment with only mujoco, mujoco-warp and warp-lang (run it
there with ``--xml /tmp/pair_affine.xml``).
"""
import sys
from importlib.metadata import version

import mujoco
import mujoco_warp as mjw
import numpy as np
import warp as wp

XML = "/tmp/pair_affine.xml"
if "--xml" in sys.argv:
    XML = sys.argv[sys.argv.index("--xml") + 1]
else:  # the default pair as the Warp backend builds it: affine servos, DIAGEXACT off
    import math

    from undulate import Scene
    from undulate.scene import scene_spec

    spec, _ = scene_spec(Scene(phases_rad=(0.0, math.pi / 2)), 0.0006666666666666666, servo="affine")
    spec.option.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
    spec.compile()
    with open(XML, "w") as f:
        f.write(spec.to_xml())
wp.config.quiet = True
wp.init()
m = mujoco.MjModel.from_xml_path(XML)
d = mujoco.MjData(m); mujoco.mj_forward(m, d)
with wp.ScopedDevice("cpu"):
    mw = mjw.put_model(m)
    dw = mjw.put_data(m, d, nworld=4, nconmax=64, njmax=256)
    counts = {"all": 0}
    mods = set()
    launch, launch_tiled = wp.launch, wp.launch_tiled
    def rec(real):
        def stub(kernel, *a, **k):
            dim = k["dim"] if "dim" in k else a[0]
            n = np.prod(dim) if not isinstance(dim, int) else dim
            if n > 0:
                counts["all"] += 1
                mods.add(kernel.key)
            return None
        return stub
    try:
        mw.opt.graph_conditional = False
    except Exception:
        pass
    iters = int(m.opt.iterations)
    wp.launch, wp.launch_tiled = rec(launch), rec(launch_tiled)
    try:
        mjw.step(mw, dw)
    finally:
        wp.launch, wp.launch_tiled = launch, launch_tiled
    print(f"mujoco {mujoco.__version__}, mujoco-warp {version('mujoco-warp')}, warp-lang {version('warp-lang')}: "
          f"{counts['all']} non-empty launches a step with {iters} solver iterations unrolled; {len(mods)} distinct kernels")
    # the same with 1 solver iteration: the rest of the step
    m.opt.iterations = 1
    mw = mjw.put_model(m)
    try:
        mw.opt.graph_conditional = False
    except Exception:
        pass
    counts["all"] = 0
    wp.launch, wp.launch_tiled = rec(launch), rec(launch_tiled)
    try:
        mjw.step(mw, dw)
    finally:
        wp.launch, wp.launch_tiled = launch, launch_tiled
    print(f"  with 1 solver iteration: {counts['all']} launches")
