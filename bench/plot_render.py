#!/usr/bin/python3
"""bench/render_ply.py at a chosen resolution (it saves at its figure's 110 dpi).

    /usr/bin/python3 bench/plot_render.py IN.ply OUT.png [--dpi 80] [render_ply.py's options]

Sets matplotlib's savefig.dpi and runs render_ply.main() unchanged, so the picture is the
same, only smaller (dpi 80: ~640 x 640 pixels, well under 300 KB for fandisk).
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render_ply  # noqa: E402


def main():
    argv = sys.argv[1:]
    dpi = 80.0
    if "--dpi" in argv:
        at = argv.index("--dpi")
        dpi = float(argv[at + 1])
        del argv[at:at + 2]
    matplotlib.rcParams["savefig.dpi"] = dpi
    sys.argv = [sys.argv[0]] + argv
    render_ply.main()


if __name__ == "__main__":
    main()
