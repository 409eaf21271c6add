"""AVR cycles of the device's wrench processing: the low-pass filter (six axes) and the tool
transform, on the ATmega328P at 16 MHz in simavr, built as the board builds it (-Os).

    .venv/bin/python tools/bench_wrenchpath.py
"""
from __future__ import annotations

import numpy as np

from delta6.build import avrbuild
from delta6.sim import avrsim

F_CPU = avrbuild.NANO.f_cpu


def main() -> None:
    src = avrbuild.REPO_ROOT / "firmware"
    core = src / "lib" / "delta6_core" / "src"
    # The firmware's float multiply (src/fast_mulsf3.S) too, as every board image links it.
    image = avrbuild.build_image(
        "wrenchpath-bench", [src / "bench" / "wrenchpath_bench.cpp", core / "delta6_filter.cpp",
                             core / "delta6_toolframe.cpp", src / "src" / "fast_mulsf3.S"],
        [core], arduino=False)
    result = avrsim.run(image.elf)
    base = np.mean(result.spans(5, 6))
    for label, (start, stop) in (("low-pass filter, 6 axes", (1, 2)),
                                 ("tool transform", (3, 4))):
        spans = np.array(result.spans(start, stop)) - base
        print(f"{label:24s} mean {spans.mean():7.0f} cycles, max {spans.max():7.0f} "
              f"({spans.mean() / F_CPU * 1e6:5.0f} us at {F_CPU / 1e6:g} MHz), {len(spans)} runs")
    print(f"image: flash {image.sizes.flash} B (the two modules and the float library)")


if __name__ == "__main__":
    main()
