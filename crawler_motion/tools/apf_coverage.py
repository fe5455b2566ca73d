"""``crawler-motion coverage --map MAP.yaml --area X0 Y0 X1 Y1 --spacing D [--footprint F]``:
a coverage route of a rectangular area of a map_server map, slice by slice with the improved
potential field (`navigation.apf.coverage`).

Prints the route as CSV ``x,y`` (metres, map frame) on stdout and one line on stderr: the
covered share of the area's free cells the disc can reach (and of all its free cells), the
overlap, the route length, the slices and clean-up legs, and any slice skipped or leg
trapped. Exit 0: every slice done; 2: a slice skipped or a leg trapped
(the route is still printed); 1: bad input, with a one-line error and no route.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.navigation.apf.coverage import cover
from crawler_motion.navigation.apf.planner import PlanSettings
from crawler_motion.tools.apf_path import TRAPPED, Parser, add_field_options, field_of, write_csv

PROG = "crawler-motion coverage"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = Parser(prog=PROG, description=__doc__.splitlines()[0])
    add_field_options(parser)
    parser.add_argument("--area", type=float, nargs=4, required=True,
                        metavar=("X0", "Y0", "X1", "Y1"))
    parser.add_argument("--spacing", type=float, required=True, help="slice spacing D [m]")
    parser.add_argument("--footprint", type=float, default=None,
                        help="radius of the sensor/tool footprint [m] (default: the disc's)")
    args = parser.parse_args(argv)
    try:
        fld = field_of(args)
        footprint = fld.radius if args.footprint is None else args.footprint
        res = cover(fld, tuple(args.area), args.spacing, footprint,
                    PlanSettings(step=args.step))
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    try:
        write_csv(np.asarray(res.route))
    except BrokenPipeError:
        return TRAPPED if res.problems else 0
    tail = "; ".join(res.problems) if res.problems else "every slice done"
    print(f"covered {100 * res.share:.1f} % of the free cells the disc can reach "
          f"({100 * res.share_free:.1f} % of all free cells); overlap "
          f"{100 * res.overlap:.1f} %; length {res.length:.3f} m; {res.slices} slices, "
          f"{res.cleanups} clean-up legs; {tail}", file=sys.stderr)
    return TRAPPED if res.problems else 0
