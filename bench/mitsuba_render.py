#!/usr/bin/env python3
"""Render a scene written by `beamlight export-mitsuba` with Mitsuba 3 for a wall-time budget
or a sample count, the way `beamlight render --time` does: independent passes (each its own
seed) averaged, weighted by their samples, and no pass started that would overrun the budget
(estimated from the mean time per sample so far). The budget counts from this script's start,
so import, scene loading and JIT compilation are included, as beamlight's start-up is.

Used by `cargo xtask bench` (xtask/src/bench/mitsuba.rs); needs `pip install mitsuba`.
The fast `llvm_ad_rgb` variant needs Debian's libllvm19 (`apt-get install libllvm19`; found at
/usr/lib/x86_64-linux-gnu/libLLVM-19.so, or set DRJIT_LIBLLVM_PATH); otherwise `scalar_rgb`.

usage: mitsuba_render.py SCENE.xml OUT.exr (--time SECONDS | --spp N) [--seed S]
                         [--variant V] [--json FILE] [--integrator volpath|volpathmis]
"""
import time

T0 = time.perf_counter()

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402

LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"


def pick_variant(requested):
    import mitsuba as mi

    if requested:
        mi.set_variant(requested)
        return requested
    if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LLVM19):
        os.environ["DRJIT_LIBLLVM_PATH"] = LLVM19
    if "DRJIT_LIBLLVM_PATH" in os.environ:
        try:
            mi.set_variant("llvm_ad_rgb")
            return "llvm_ad_rgb"
        except Exception as e:  # LLVM missing or too old
            print(f"mitsuba_render: llvm_ad_rgb unavailable ({e}); using scalar_rgb", file=sys.stderr)
    mi.set_variant("scalar_rgb")
    return "scalar_rgb"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("output")
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--time", type=float)
    g.add_argument("--spp", type=int)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variant")
    ap.add_argument("--json")
    ap.add_argument("--integrator", default=None, help="replace the scene's integrator (volpathmis)")
    ap.add_argument("--chunk", type=int, default=64, help="most samples per pass with --spp")
    args = ap.parse_args()

    import mitsuba as mi

    variant = pick_variant(args.variant)
    scene = mi.load_file(args.scene)
    integrator = None
    if args.integrator:
        integrator = mi.load_dict({"type": args.integrator, "max_depth": -1})
    loaded = time.perf_counter()

    acc = None
    total_spp = 0
    passes = 0

    def render(spp):
        nonlocal acc, total_spp, passes
        seed = args.seed * 1_000_003 + passes
        t = time.perf_counter()
        img = mi.render(scene, integrator=integrator, spp=spp, seed=seed)
        img = mi.TensorXf(img)
        if variant.startswith("llvm"):
            import drjit as dr

            dr.eval(img)
        dt = time.perf_counter() - t
        acc = img * spp if acc is None else acc + img * spp
        total_spp += spp
        passes += 1
        return dt

    if args.spp is not None:
        left = args.spp
        while left > 0:
            k = min(left, args.chunk)
            render(k)
            left -= k
    else:
        budget = args.time
        # Mitsuba compiles a kernel per sample count, so passes keep one count: two 1-spp
        # passes (the first compiles) measure the speed, then every pass has k samples,
        # about a twentieth of the budget, and none starts that would overrun (estimated
        # from the latest pass, which after the first k-pass has no compilation in it).
        render(1)
        last = None
        if time.perf_counter() - T0 < budget:
            last = render(1)
            k = max(1, int(0.05 * budget / max(last, 1e-6)))
            while time.perf_counter() - T0 + (last * k if passes == 2 else last) <= budget:
                last = render(k)

    image = acc / total_spp
    mi.Bitmap(image).write(args.output)
    done = time.perf_counter()
    record = {
        "renderer": "mitsuba3",
        "mitsuba_version": mi.__version__,
        "variant": variant,
        "integrator": args.integrator or "scene (volpath)",
        "spp": total_spp,
        "passes": passes,
        "startup_seconds": loaded - T0,
        "render_seconds": done - loaded,
        "process_seconds": done - T0,
    }
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)
    print(json.dumps(record))


if __name__ == "__main__":
    main()
