"""Our render against the stored Cycles references over seeds, with the regathered ends'
secondary caustic from their gather points (integrator.SECONDARY_FROM_GATHER_POINTS) off
and on (regather29): brightness, relMSE and HDR-FLIP per scene and seed, through the
add-on at default settings (tools/accuracy_scenes, as tests/test_accuracy_cycles.py).

    .venv/bin/python bench/bench_regather_seeds.py [--scenes figure7_blocker,...] [--seeds 1,2]
"""
import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="figure7_blocker,figure7_mirror,mirror_glass,"
                                        "caustic_soft_spot")
    ap.add_argument("--seeds", default="1,2")
    args = ap.parse_args(argv)
    import accuracy_scenes as acc
    import engine.integrator as integrator
    print("| scene | seed | points' share | brightness | relMSE | FLIP |")
    print("|---|---:|---|---:|---:|---:|")
    for name in args.scenes.split(","):
        ref = acc.load_reference(name)
        for seed in (int(s) for s in args.seeds.split(",")):
            for flag in (False, True):
                integrator.SECONDARY_FROM_GATHER_POINTS = flag
                ours, _ = acc.render_ours(name, seed=seed)
                print(f"| {name} | {seed} | {'on' if flag else 'off'} | "
                      f"{acc.brightness(ours, ref):.4f} | {acc.relmse(ours, ref):.4f} | "
                      f"{acc.flip(ours, ref):.4f} |", flush=True)


if __name__ == "__main__":
    main()
