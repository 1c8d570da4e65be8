"""Request model of the paper's figures (``GET /v1/figures/{name}``, ``rsf figure``,
``Client.figure`` / ``Client.figure_data``, the dashboard), and the catalogue of the
figures one may ask for.

A figure is named by ``name`` (:data:`FIGURES`) and computed at a ``quality``: 'paper'
(fine grids, the default at every door) or 'draft' (coarse grids, a few seconds a
figure).  Its data come from :mod:`rsfapp.adapter.figures` (rsfcore, no matplotlib);
images are drawn from those data by rsfplots.  The answer's format (PNG, SVG or the data
as JSON, :data:`FIGURE_FORMATS`, default :data:`DEFAULT_FIGURE_FORMAT`) is how a door
renders the answer, not part of the question.

Parameter values of each figure are the paper's (captions and text of Ciardo & Viesca);
where the printed caption contradicts itself the choice is stated in the ``note``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pydantic import field_validator

from ._base import F
from ._base import Model as _Model

__all__ = [
    "DEFAULT_FIGURE_FORMAT",
    "DEFAULT_FIGURE_QUALITY",
    "FIGURES",
    "FIGURE_FORMATS",
    "FIGURE_QUALITIES",
    "FigureInfo",
    "FigureQuality",
    "FigureRequest",
    "IMAGE_FORMATS",
]

#: Qualities of a figure: 'paper' (fine grids) or 'draft' (coarse grids, faster).
FigureQuality = Literal["paper", "draft"]
FIGURE_QUALITIES: tuple[str, ...] = ("paper", "draft")
#: The quality of a request that gives none, at every door.
DEFAULT_FIGURE_QUALITY: FigureQuality = "paper"
#: Image formats of a figure (drawn by rsfplots).
IMAGE_FORMATS: tuple[str, ...] = ("png", "svg")
#: Every format of a figure's answer: an image, or the data behind it as JSON.
FIGURE_FORMATS: tuple[str, ...] = (*IMAGE_FORMATS, "json")
#: The format of a request that gives none (HTTP ``format``, the client's ``format``,
#: ``rsf figure`` without ``--out``/``--json`` writes NAME.png).
DEFAULT_FIGURE_FORMAT = "png"


@dataclass(frozen=True)
class FigureInfo:
    """One reproducible figure: its name, the paper's label and a one-line caption of what
    is plotted, and how the regenerated figure deviates from the printed one (``note``)."""

    name: str
    label: str  # the paper's \\label, e.g. 'fig: trajectories 1'
    caption: str
    note: str = ""

    def summary(self) -> dict[str, str]:
        """{name, caption ('<label>: <caption>'), label, note, url} as listed by every door."""
        return {
            "name": self.name,
            "caption": f"{self.label}: {self.caption}",
            "label": self.label,
            "note": self.note,
            "url": f"/v1/figures/{self.name}",
        }


_CATALOGUE = (
    FigureInfo(
        "velocity-step",
        "fig: velocity stepping experiments",
        "analytic stress response (eq: delta tau) Delta tau/(b sigma) vs slip delta/Dc after "
        "velocity steps V2/V1 = 10^{+-1..4}, one panel per eps from 0 (slip law) to 1 (aging law)",
        "eps = 0, 0.2, 0.4, 0.6, 0.8, 1 (the caption does not list the panels' eps)",
    ),
    FigureInfo(
        "trajectories-kcrit",
        "fig: trajectories 1",
        "U = const. contours in (phi, psi) for v_o = 1, b/a = 5/4, kappa = kappa_crit = 1/4, "
        "eps in {0, 0.3, 0.6, 1}; steady-state line, critical trajectory U = 0 (red), "
        "numerical trajectories from velocity jumps (black)",
    ),
    FigureInfo(
        "critical-jump-kcrit",
        "fig: limiting perturbation 1",
        "(a) critical velocity jump dphi_crit vs eps for b/a = 5/4, kappa = kappa_crit, "
        "with the slip- and aging-law asymptotes; (b) slip law, dphi_crit vs a/b with the "
        "sqrt(2 a/b) scaling and the excluded point a/b = 1",
    ),
    FigureInfo(
        "rate-neutral",
        "fig: rate neutral",
        "phase-plane trajectory for rate-neutral friction b/a = 1, kappa = 1, eps = 0.01 after "
        "a velocity jump dphi = 1: spirals back to steady state",
        "b/a = 1 exactly is outside rsfcore's range (1, 1e6]; computed at b/a = 1 + 1e-9 "
        "(tests compare with a direct b/a = 1 integration)",
    ),
    FigureInfo(
        "stability-diagram-velocity",
        "fig: stability diagram2",
        "(a) critical velocity jump vs kappa/kappa_crit for several eps (b/a = 2, v_o = 1); "
        "(b) trajectories for dphi = 1, 1.5, 2.5, 3 at kappa = 2 kappa_crit, eps = 0.25 with "
        "U_kcrit level lines (red dashed)",
    ),
    FigureInfo(
        "stability-diagram-load-point",
        "fig: stability diagram",
        "(a) critical load-point jump vs kappa/kappa_crit for several eps (b/a = 2); "
        "(b) trajectories for dv_o/v_o = 4, 9, 12, 14 at kappa = 2 kappa_crit, eps = 0.25",
        "the caption reads 12.66 off the figure; the critical jump is 12.6842",
    ),
    FigureInfo(
        "trajectories-vo0-soft",
        "fig: trajectories 2",
        "stationary load point v_o = 0, b/a = 2, kappa = 0.5 < kappa_crit, eps in "
        "{0, 0.3, 0.6, 1}: U contours (eq: trajectories 2), critical line (red), acceleration "
        "line (orange), numerical trajectories",
    ),
    FigureInfo(
        "trajectories-vo0-stiff",
        "fig: trajectories 3",
        "stationary load point v_o = 0, b/a = 2, kappa = 3/2 > kappa_crit, eps in "
        "{0, 0.6, 0.7, 1}: unstable orbits vanish above eps_crit = 2/3",
        "the caption says kappa = 2, which gives eps_crit = 1/2 and no critical line at "
        "eps = 0.6; kappa = 3/2 (the text) gives the caption's eps_crit = 2/3 and is used",
    ),
    FigureInfo(
        "critical-jump-vo0",
        "fig: limiting perturbation 2",
        "v_o = 0: (a) dphi_crit vs eps for b/a = 2, kappa = 0.5, 1, 1.5 with eps_crit = 2/3; "
        "(b) dphi_crit vs a/b for kappa = 1 and eps in {0, 0.25, 0.5, 0.75, 1} with the "
        "(a/b)_crit asymptotes",
    ),
    FigureInfo(
        "periodic-response",
        "fig: periodic motion",
        "kappa = kappa_crit = 1, b/a = 2, eps = 0.25, load-point jump dv_o/v_o = 1.33 "
        "(critical 4/3): psi, phi, Theta vs slip and the closed phase-plane orbit",
        "the caption's critical value 1.34 is 4/3 = 1.3333 (closed form 1/(kappa_crit (1 - eps)))",
    ),
    FigureInfo(
        "non-periodic-response",
        "fig: non-periodic motion",
        "load-point jumps 4, 9, 12, 14 at kappa = 2 kappa_crit, b/a = 2, eps = 0.25: psi, phi, "
        "theta V*/Dc vs slip",
    ),
    FigureInfo(
        "continuum-modes",
        "fig: continuum models",
        "smallest-eigenvalue eigenmodes (red curves of the schematic) of cases B, D and E with "
        "k/k_* (tab: table)",
        "the schematic itself is not computed; case B's converged eigenvalue is "
        "1.1577738836976 (the paper prints 1.157773882)",
    ),
)

#: Every figure one may ask for, by name, in the paper's order.
FIGURES: dict[str, FigureInfo] = {f.name: f for f in _CATALOGUE}
_NAMES_TEXT = "one of " + ", ".join(FIGURES)


class FigureRequest(_Model):
    """One figure of the paper, regenerated from rsfcore at a quality."""

    name: str = F(
        ...,
        _NAMES_TEXT,
        "Figure name (GET /v1/figures and `rsf figure --list` list them with captions).",
        max_length=200,
    )
    quality: FigureQuality = F(
        DEFAULT_FIGURE_QUALITY,
        "'paper' or 'draft'",
        "'paper' (fine grids) or 'draft' (coarse grids, a few seconds a figure).",
        name="quality",
    )

    @field_validator("name")
    @classmethod
    def _known(cls, v: str) -> str:
        if v not in FIGURES:
            raise ValueError(f"unknown figure {v!r}; {_NAMES_TEXT}")
        return v
