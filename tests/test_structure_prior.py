"""The furniture prior of the structure search (models/articulation/structure_prior.py):
two drawers only ever pulled together end up both on the carcass, where the BIC alone fixes
one to the other; data that show a front on a front still win; independent drawers are
unchanged."""

import json

import numpy as np
import pytest

from mmlearn.apps import fit_structure as app
from mmlearn.diagrams.common.object_tracks import cabinet_scenario, cabinet_together_scenario
from mmlearn.models.articulation.graph import fit_structure
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.sim import drawer_with_lid_tracks
from mmlearn.models.articulation.structure_prior import StructurePrior, infer_roles

OBS = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(5))
CARCASS = ((0, 1), (0, 2))


def _both(tr, seed):
    r0 = fit_structure(tr.poses, part_names=tr.parts, obs=OBS, rng=seed)
    r1 = fit_structure(tr.poses, part_names=tr.parts, obs=OBS, rng=seed, prior=StructurePrior(),
                       pair_models=r0.pair_models)
    return r0, r1


@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.slow),
                                  pytest.param(3, marks=pytest.mark.slow)])
def test_drawers_pulled_together_hang_on_the_carcass(seed):
    r0, r1 = _both(cabinet_together_scenario(rng=seed), seed)
    assert r0.best.edges != CARCASS                   # the BIC alone: a drawer on a drawer
    assert "rigid" in r0.best.models.values()
    assert r1.best.edges == CARCASS and r1.best.dof == 1
    assert set(r1.best.models.values()) == {"prismatic"}
    assert r1.best.prior_cost == 0.0
    assert r1.roles == {"cabinet": "carcass", "upper_drawer": "front", "lower_drawer": "front"}
    # the data cannot tell them apart: the chain fits no better
    chain = min((e for e in r1.evaluated if e.edges != CARCASS and not e.has_loop),
                key=lambda e: e.bic)
    assert abs(chain.log_likelihood - r1.best.log_likelihood) < 5.0


@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_a_lid_on_a_drawer_stays_on_the_drawer(seed):
    Y = drawer_with_lid_tracks(seed)
    obs = ObservationModel(sigma_pos=0.005, sigma_orient=0.02)
    names = ["carcass", "drawer", "lid"]
    r0 = fit_structure(Y, part_names=names, obs=obs, rng=seed)
    r1 = fit_structure(Y, part_names=names, obs=obs, rng=seed, prior=StructurePrior(),
                       pair_models=r0.pair_models)
    for r in (r0, r1):
        assert r.best.edges == ((0, 1), (1, 2))
        assert r.best.models == {(0, 1): "prismatic", (1, 2): "revolute"}
    assert r1.best.prior_cost == pytest.approx(8.0 * np.log(80))


def test_independent_drawers_unchanged():
    tr = cabinet_scenario(rng=3)
    r0, r1 = _both(tr, 3)
    assert r0.best.edges == r1.best.edges == CARCASS
    assert r0.best.models == r1.best.models and r0.best.dof == r1.best.dof == 2


def test_roles_inferred_from_motion_and_names():
    tr = cabinet_together_scenario(rng=0)
    floor = np.tile([0, 0, 0, 0, 0, 0, 1.0], (tr.poses.shape[1], 1))
    Y = np.concatenate([tr.poses, floor[None]])
    roles = infer_roles(Y, [*tr.parts, "floor"])
    assert roles == {"cabinet": "carcass", "upper_drawer": "front", "lower_drawer": "front",
                     "floor": "floor"}
    p = StructurePrior(roles={"cabinet": "front"})
    assert p.resolve_roles(Y, [*tr.parts, "floor"])["cabinet"] == "front"
    assert p.edge_params("front", "floor") == 8.0 and p.edge_params("carcass", "floor") == 0.0


def test_prior_bad_input():
    tr = cabinet_together_scenario(rng=0)
    with pytest.raises(ValueError, match="unknown role"):
        StructurePrior(roles={"cabinet": "wardrobe"}).validate()
    with pytest.raises(ValueError, match="not observed"):
        StructurePrior(roles={"table": "front"}).resolve_roles(tr.poses, tr.parts)
    with pytest.raises(ValueError, match="front_front_params"):
        StructurePrior(front_front_params=-1.0).validate()
    with pytest.raises(ValueError, match="n must be"):
        StructurePrior().cost([(0, 1)], ["front", "front"], 1)


def test_fit_structure_app_with_the_prior(capsys):
    from importlib.resources import files

    csv = str(files("mmlearn.apps.examples") / "two_drawers_pulled_together.csv")
    assert app.main([csv, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert app.main([csv, "--json", "--furniture-prior"]) == 0
    out = json.loads(capsys.readouterr().out)
    pairs = sorted((e["a"], e["b"]) for e in out["edges"])
    assert pairs == [("cabinet", "lower_drawer"), ("cabinet", "upper_drawer")]
    assert out["dof"] == 1 and out["prior_cost"] == 0.0 and out["score"] == out["bic"]
    assert sorted((e["a"], e["b"]) for e in plain["edges"]) != pairs
    with pytest.raises(SystemExit) as e:
        app.main([csv, "--roles", "cabinet=carcas"])
    assert e.value.code == 2
    assert "NAME=ROLE" in capsys.readouterr().err
