"""Figure helpers shared by the studies and the demo: legends a newcomer can read.

Every mark drawn by :func:`splatplan.scenes.builtin.stonehenge.plot_top_view` gets a legend entry here
(grey outlines, coloured stones, red dashed outlines), so no figure relies on a reader knowing
the plotting code.
"""

from __future__ import annotations


def top_view_handles(scene, z: float, *, footprints: bool = True, inflate: float = 0.0, alpha: float = 1.0) -> list:
    """Legend handles for the marks of ``plot_top_view(ax, scene, z, footprints=..., inflate=...)``.

    One entry per stone kind cut by the plane (its fill colour), one for the grey footprint
    outlines (when drawn) and one for the red dashed configuration-space outline (when drawn).
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from ..scenes.builtin.stonehenge import LABEL_COLORS, box_cross_section

    kinds = []
    for box, lab in zip(scene.boxes, scene.labels):
        if lab != "ground" and lab not in kinds and box_cross_section(box, z) is not None:
            kinds.append(lab)
    handles: list[Patch | Line2D] = [
        Patch(fc=LABEL_COLORS.get(k, "0.4"), ec="k", lw=0.5, alpha=alpha, label=f"stone at z = {z:g}: {k.replace('_', ' ')}")
        for k in kinds
    ]
    if footprints:
        handles.append(Line2D([], [], color="0.7", lw=0.8, label="stone outline from above (any height)"))
    if inflate > 0:
        handles.append(Line2D([], [], color="tab:red", ls="--", lw=0.8, label=f"stone grown by the robot radius r = {inflate:g}\n(the robot centre must stay outside)"))
    return handles

