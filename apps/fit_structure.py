"""Learn the kinematic structure (tree or graph with loops) and DOFs of a multi-part object.

Usage::

    python -m mmlearn.apps.fit_structure FILE [--search tree|local|exhaustive]
        [--reduce-dofs] [--models rigid,prismatic,revolute,gp] [--sigma-pos M]
        [--sigma-orient RAD] [--seed N] [--json] [--plot OUT.png]
        [--furniture-prior] [--roles NAME=ROLE,...]

FILE is CSV with the header ``t,part,x,y,z,qx,qy,qz,qw`` (t in seconds, position in metres,
unit quaternion; one row per observed part per time step, a missing row = not observed).

``--json`` prints::

    {"parts": [...], "edges": [{"a", "b", "model", "bic"}], "dof": int, "has_loop": bool,
     "bic": float, "seconds": float}

``bic`` is the global BIC of the selected graph (Eq. 4.54 with the DOF penalty, evaluated on
the time steps where every part is observed); an edge's ``bic`` is its link model's BIC.
``--furniture-prior`` adds the furniture prior
(:class:`mmlearn.models.articulation.structure_prior.StructurePrior`: fronts hang on the
carcass, not on each other or on the floor) to the search; the JSON then also has
``prior_cost``, ``score`` (BIC + prior cost, what was minimised) and ``roles`` (each part's
role, inferred from its motion unless ``--roles`` names it: carcass, front or floor).

Bad input prints the problem on stderr and exits with status 2.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file,
                                     fail, nonneg_float, nonneg_int, pos_float)
from mmlearn.apps.common.cli import save_figure
from mmlearn.models.articulation.link import DEFAULT_GAMMA_WEIGHT, ObservationModel, make_model
from mmlearn.models.articulation.graph import SEARCH_MODES, fit_structure, read_parts_csv
from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES

__all__ = ["run", "main"]


def run(*, path, search: str = "local", reduce_dofs: bool = False, models=DEFAULT_CANDIDATES,
        sigma_pos: float = 0.01, sigma_orient: float = float(np.deg2rad(5.0)),
        gamma_weight: float = DEFAULT_GAMMA_WEIGHT, seed: int = 0,
        plot: str | None = None, furniture_prior: bool = False,
        roles: dict | None = None) -> dict:
    """Fit the structure of the object in CSV ``path``; returns the --json dictionary.
    ``furniture_prior`` / ``roles``: see the module docstring."""
    if search not in SEARCH_MODES:
        raise ValueError(f"unknown search {search!r}; choose from {', '.join(SEARCH_MODES)}")
    if isinstance(models, str):
        models = [m.strip() for m in models.split(",") if m.strip()]
    for m in models:
        make_model(m)
    names, times, Y = read_parts_csv(path)
    if len(names) < 2:
        raise ValueError(f"{path}: need at least 2 parts, found {len(names)} ({names})")
    obs = ObservationModel(sigma_pos=sigma_pos, sigma_orient=sigma_orient,
                           gamma_weight=gamma_weight)
    prior = None
    if furniture_prior or roles:
        from mmlearn.models.articulation.structure_prior import StructurePrior

        prior = StructurePrior(roles=dict(roles or {}))
    r = fit_structure(Y, part_names=names, search=search, reduce_dofs=reduce_dofs,
                      models=models, obs=obs, rng=seed, prior=prior)
    out = r.to_dict()
    if plot:
        _plot(r, Y, plot)
    return out


def _plot(r, Y, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    for k, nm in enumerate(r.part_names):
        ax.plot(Y[k, :, 0], Y[k, :, 1], Y[k, :, 2], ".", ms=2, label=nm)
    t = int(np.flatnonzero(np.isfinite(Y).all(axis=2).all(axis=0))[0]) \
        if np.isfinite(Y).all(axis=2).all(axis=0).any() else 0
    for i, j in r.best.edges:
        a, b = Y[i, t, :3], Y[j, t, :3]
        ax.plot([a[0], b[0]], [a[1], b[1]], [a[2], b[2]], "k-", lw=2)
        m = (a + b) / 2
        ax.text(m[0], m[1], m[2], r.best.models[(i, j)], fontsize=8)
    ax.set_title(f"DOF {r.best.dof}, BIC {r.best.bic:.0f}")
    ax.legend(fontsize=7)
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _roles(text: str) -> dict:
    """``name=role,...`` -> dict (argparse type)."""
    import argparse

    from mmlearn.models.articulation.structure_prior import ROLES

    out = {}
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        name, sep, role = item.partition("=")
        if not sep or not name.strip() or role.strip() not in ROLES:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected NAME=ROLE with ROLE one of {', '.join(ROLES)}")
        out[name.strip()] = role.strip()
    if not out:
        raise argparse.ArgumentTypeError("no NAME=ROLE given")
    return out


def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m mmlearn.apps.fit_structure",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="CSV file t,part,x,y,z,qx,qy,qz,qw")
    ap.add_argument("--search", default="local", choices=SEARCH_MODES,
                    help="structure search (default: local)")
    ap.add_argument("--reduce-dofs", action="store_true",
                    help="estimate the DOFs of graphs with loops by PCA (Eq. 4.55-4.56)")
    ap.add_argument("--models", default=",".join(DEFAULT_CANDIDATES),
                    help="candidate link models (comma separated)")
    ap.add_argument("--sigma-pos", type=pos_float, default=0.01, help="position noise, m")
    ap.add_argument("--sigma-orient", type=pos_float, default=float(np.deg2rad(5.0)),
                    help="orientation noise, rad")
    ap.add_argument("--gamma-weight", type=nonneg_float, default=DEFAULT_GAMMA_WEIGHT,
                    help="weight w of the outlier prior p(gamma) ~ exp(-w gamma), per "
                         "observation (default ln(100)/0.05 ~ 92)")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="random seed")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--plot", default=None, help="write a PNG of the structure")
    ap.add_argument("--furniture-prior", action="store_true",
                    help="prefer structures where fronts hang on the carcass (a prior beside "
                         "the BIC)")
    ap.add_argument("--roles", type=_roles, default=None,
                    help="parts' roles for the prior, e.g. cabinet=carcass,lid=front "
                         "(carcass, front or floor; implies --furniture-prior)")
    a = ap.parse_args(argv)
    try:
        if not Path(a.file).is_file():
            raise UsageError(f"{a.file}: file not found" if not Path(a.file).exists()
                             else f"{a.file}: not a file")
        check_out_file("--plot", a.plot)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        out = run(path=a.file, search=a.search, reduce_dofs=a.reduce_dofs, models=a.models,
                  sigma_pos=a.sigma_pos, sigma_orient=a.sigma_orient,
                  gamma_weight=a.gamma_weight, seed=a.seed, plot=a.plot,
                  furniture_prior=a.furniture_prior, roles=a.roles)
    except (ValueError, FileNotFoundError, OSError) as e:
        return fail(ap.prog, str(e))
    if a.json:
        print(json.dumps(out))
    else:
        print(f"parts: {', '.join(out['parts'])}")
        for e in out["edges"]:
            print(f"  {e['a']} - {e['b']}: {e['model']} (link BIC {e['bic']:.1f})")
        print(f"DOF {out['dof']}, loop: {out['has_loop']}, BIC {out['bic']:.1f}, "
              f"{out['seconds']:.2f} s")
        if "roles" in out:
            print("roles: " + ", ".join(f"{k} {v}" for k, v in out["roles"].items())
                  + f"; prior cost {out['prior_cost']:.1f}, score {out['score']:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
