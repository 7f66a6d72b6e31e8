"""What a Drake MultibodyPlant makes of an SDFormat text, as a JSON-able summary.

Used by ``tests/test_sdf_writer.py`` to check that the SDF writer's output is the model the
string templates it replaced produced (the reference summaries in
``tests/data/sdf_reference/`` were made from those templates). Regenerate them, after a
deliberate change to a model, with::

    python tests/sdf_summary.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "sdf_reference"
REFERENCE = DATA / "summaries.json"
ARTICULATED = DATA / "articulated_cabinet.json"


def cases() -> dict:
    """name -> zero-argument callable returning SDFormat text."""
    from mmlearn.models.articulation.io import load_model, to_sdf
    from mmlearn.sdf import builders, mechanisms, objects

    out = {f"shipped/{k}": v for k, v in builders.DEFAULT_MODELS.items()}
    out.update({
        "arm_2dof_failures": lambda: builders.arm_sdf(2, tool="none", failure_joints=True),
        "arm_4dof_failures": lambda: builders.arm_sdf(4, tool="none", failure_joints=True),
        "arm_7dof_gripper_failures_posed": lambda: builders.arm_sdf(
            7, failure_joints=True, model_name="robot", pose=(0.5, -0.2, 0, 0, 0, 0.3)),
        "arm_7dof_mobile_gripper": lambda: builders.arm_sdf(7, mobile_base=True),
        "arm_7dof_hook_mobile_failures": lambda: builders.arm_sdf(
            7, tool="hook", mobile_base=True, failure_joints=True),
        "cabinet_custom_posed": lambda: builders.cabinet_sdf(
            builders.CabinetSpec(width=0.7, height=1.0, door_damping=1.3), model_name="c2",
            pose=(1.2, 0.1, 0, 0, 0, 3.0)),
        "floor_3m": lambda: builders.floor_sdf(3.0),
    })
    for name in objects.OBJECTS:
        out[f"object/{name}"] = lambda name=name: objects.object_sdf(name)
    for kind in mechanisms.KINDS:
        for seed in (0, 3):
            out[f"mechanism/{kind}/{seed}"] = (
                lambda kind=kind, seed=seed: mechanisms.mechanism_sdf(
                    mechanisms.sample_mechanism(kind, seed)))
    out["mechanism/default_named"] = lambda: mechanisms.mechanism_sdf(
        mechanisms.MechanismSpec(), model_name="furniture")
    out["articulation/cabinet"] = lambda: to_sdf(load_model(ARTICULATED),
                                                  model_name="cabinet_learned")
    out["articulation/cabinet_free"] = lambda: to_sdf(load_model(ARTICULATED),
                                                       weld_root=False)
    out["articulation/single_link"] = lambda: to_sdf(load_model(ARTICULATED).edges[0].model)
    return out


def _pose(X) -> list:
    return [round(float(v), 12) for v in
            (*X.translation(), *X.rotation().ToQuaternion().wxyz())]


def summarize(text: str) -> dict:
    """Bodies, joints, frames, actuators, force elements and geometries of ``text``."""
    from pydrake.geometry import Role
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.multibody.tree import ForceElementIndex
    from pydrake.systems.framework import DiagramBuilder

    plant, sg = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    (mi,) = Parser(plant).AddModelsFromString(text, "sdf")
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    inspector = sg.model_inspector()
    r = lambda a: [round(float(v), 12) for v in np.ravel(a)]  # noqa: E731
    out = {"model": plant.GetModelInstanceName(mi), "bodies": {}, "joints": {}, "frames": {},
           "actuators": {}, "force_elements": [], "num_positions": plant.num_positions()}
    first_body = min(int(i) for i in plant.GetBodyIndices(mi))
    for i in plant.GetBodyIndices(mi):
        b = plant.get_body(i)
        M = b.default_spatial_inertia()
        geoms = []
        fid = plant.GetBodyFrameIdIfExists(b.index())
        if fid is not None:
            for role, key in ((Role.kIllustration, "visual"), (Role.kProximity, "collision")):
                for g in inspector.GetGeometries(fid, role):
                    shape = inspector.GetShape(g)
                    kind = type(shape).__name__
                    if kind == "Box":
                        dims = r(shape.size())
                    elif kind == "Cylinder":
                        dims = r([shape.radius(), shape.length()])
                    elif kind == "Sphere":
                        dims = r([shape.radius()])
                    else:
                        dims = []
                    item = {"role": key, "name": inspector.GetName(g), "shape": kind,
                            "dims": dims, "X_BG": _pose(inspector.GetPoseInFrame(g))}
                    if role == Role.kIllustration:
                        props = inspector.GetIllustrationProperties(g)
                        if props.HasProperty("phong", "diffuse"):
                            item["diffuse"] = r(props.GetProperty("phong", "diffuse").rgba)
                    geoms.append(item)
        geoms.sort(key=lambda d: (d["role"], d["name"]))
        out["bodies"][b.name()] = {
            "index": int(b.index()) - first_body,
            "mass": round(float(b.default_mass()), 12),
            "com": r(M.get_com()),
            "I_BBo": r(M.CalcRotationalInertia().CopyToFullMatrix3()),
            "X_WB": _pose(b.EvalPoseInWorld(ctx)),
            "geometries": geoms,
        }
    for i in plant.GetJointIndices(mi):
        j = plant.get_joint(i)
        d = {"type": j.type_name(), "parent": j.parent_body().name(),
             "child": j.child_body().name(),
             "X_PF": _pose(j.frame_on_parent().GetFixedPoseInBodyFrame()),
             "X_CM": _pose(j.frame_on_child().GetFixedPoseInBodyFrame()),
             "lower": r(j.position_lower_limits()), "upper": r(j.position_upper_limits()),
             "velocity": r(j.velocity_upper_limits()),
             "damping": r(j.default_damping_vector())}
        if hasattr(j, "revolute_axis"):
            d["axis"] = r(j.revolute_axis())
        elif hasattr(j, "translation_axis"):
            d["axis"] = r(j.translation_axis())
        out["joints"][j.name()] = d
    for i in plant.GetFrameIndices(mi):
        f = plant.get_frame(i)
        if f.is_body_frame() or f.name() == "" or f.name().startswith("_"):
            continue
        out["frames"][f.name()] = {"body": f.body().name(),
                                   "X_BF": _pose(f.GetFixedPoseInBodyFrame())}
    for i in plant.GetJointActuatorIndices(mi):
        a = plant.get_joint_actuator(i)
        out["actuators"][a.name()] = {"joint": a.joint().name(),
                                      "effort": round(float(a.effort_limit()), 12)}
    for i in range(plant.num_force_elements()):
        fe = plant.get_force_element(ForceElementIndex(i))
        if fe.model_instance() != mi:
            continue
        item = {"type": type(fe).__name__}
        if item["type"] == "RevoluteSpring":
            item.update(joint=fe.joint().name(), stiffness=round(float(fe.default_stiffness()), 12),
                        nominal_angle=round(float(fe.default_nominal_angle()), 12))
        out["force_elements"].append(item)
    return out


def dumps(summaries: dict) -> str:
    """The reference file's text: one line per model."""
    return "{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v, sort_keys=True)}"
                              for k, v in sorted(summaries.items())) + "\n}\n"


def main(argv=None) -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    ref = {name: summarize(build()) for name, build in cases().items()}
    REFERENCE.write_text(dumps(ref))
    print(f"{REFERENCE}: {len(ref)} models")


if __name__ == "__main__":
    main(sys.argv[1:])
