"""Draw what an MCAP file of ``spco show HOME --mcap FILE`` holds, read back with the ``mcap`` library:
the ``foxglove.SceneUpdate`` entities of ``/spco/scene`` (regions: ellipse line loops, translucent
fills, name labels) and ``/spco/teachings`` (spheres and sentences), top view of the map frame — as
Foxglove's 3D panel shows them from above. For docs/on-the-robot.md where no Foxglove app can run::

    spco show home.spco --mcap home.mcap
    python tools/mcap_plot.py home.mcap --out docs/images/foxglove_mcap.png
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def main() -> None:
    """Read the file back and draw it."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mcap", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()

    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse

    from spco.ros.foxglove import read_mcap

    back = read_mcap(args.mcap)
    meta = back["metadata"].get("spco", {})
    fig = Figure(figsize=(11, 3.6), layout="constrained", facecolor="#181c24")
    ax = fig.add_subplot()
    ax.set_facecolor("#181c24")
    counts = {"/spco/scene": 0, "/spco/teachings": 0}
    for record in back["messages"]:
        topic, update = record["topic"], record["message"]
        counts[topic] = counts.get(topic, 0) + len(update.entities)
        for entity in update.entities:
            for line in entity.lines:
                c = line.color
                xs = [p.x for p in line.points] + [line.points[0].x]
                ys = [p.y for p in line.points] + [line.points[0].y]
                ax.plot(xs, ys, color=(c.r, c.g, c.b), linewidth=1.6, zorder=3)
            for cylinder in entity.cylinders:
                c, q = cylinder.color, cylinder.pose.orientation
                angle = math.degrees(2 * math.atan2(q.z, q.w))
                centre = (cylinder.pose.position.x, cylinder.pose.position.y)
                ax.add_patch(Ellipse(centre, cylinder.size.x, cylinder.size.y, angle=angle,
                                     facecolor=(c.r, c.g, c.b), alpha=c.a, zorder=2))
            for sphere in entity.spheres:
                ax.plot(sphere.pose.position.x, sphere.pose.position.y, "o", color="white", markersize=3,
                        zorder=4)
            if topic == "/spco/scene":
                for text in entity.texts:
                    c = text.color
                    ax.text(text.pose.position.x, text.pose.position.y, text.text, color="white", fontsize=7,
                            ha="center", va="center", zorder=5,
                            bbox={"boxstyle": "round,pad=0.2", "fc": (c.r, c.g, c.b), "ec": "none",
                                  "alpha": 0.8})
    ax.set_aspect("equal")
    ax.grid(True, color="#3a4050", linewidth=0.6)
    ax.tick_params(colors="#c8c8c8")
    for side in ax.spines.values():
        side.set_color("#3a4050")
    ax.set_xlabel(f"x [m] (frame {meta.get('frame', 'map')})", color="#c8c8c8")
    ax.set_ylabel("y [m]", color="#c8c8c8")
    ax.set_title(f"{args.mcap.name}, read back with mcap: home {meta.get('home', '?')}, "
                 f"{counts['/spco/scene']} region entities on /spco/scene, "
                 f"{counts['/spco/teachings']} teachings (white dots) on /spco/teachings",
                 color="white", fontsize=9)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110, facecolor=fig.get_facecolor())
    print(f"Wrote {args.out}")


if __name__ == "__main__":
    main()
