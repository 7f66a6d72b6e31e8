"""Reproduce a task learned from recorded demonstrations with the DbnReproducer (thesis ch. 8).

A scripted teacher shows 3 times how to reach a target past an obstacle; a ``MarkerSensor``
records what it sees (``Demonstration``: hand and object marker tracks, NaN when unseen).
``learn_task`` turns them into a ``TaskModel``, the DBN of constraints: per time slice, a
Gaussian of the hand's position relative to each object. ``MakeImitationDiagram`` wires
a ``DbnReproducer`` (which steps through the slices and commands the 7-DOF arm) into a new,
seeded variation of the scene, where the target stands elsewhere.

    python examples/imitate_reach.py
"""
import numpy as np
from pydrake.all import Simulator

from mmlearn.diagrams import ImitationConfig, MakeImitationDiagram, object_positions, \
    record_demonstrations
from mmlearn.models.imitation import learn_task

demos = record_demonstrations("obstacle", 3, seed=0)
model = learn_task(demos, use_joints=False)  # the teacher's joints are not the robot's
print(f"learned {model.S} slices of {model.constraints} from {len(demos)} demonstrations")

im = MakeImitationDiagram(ImitationConfig(task="obstacle", seed=2), model=model)
context = im.diagram.CreateDefaultContext()
im.set_start(context)  # the arm at its start configuration
simulator = Simulator(im.diagram, context)
simulator.AdvanceTo(im.reproducer.duration + 1.0)

hand = im.diagram.GetOutputPort("hand").Eval(context)
target = object_positions(im.plant, context, ["target"])["target"]
print(f"hand {np.round(hand, 3)} m, target marker {np.round(target, 3)} m, "
      f"{1000 * np.linalg.norm(hand[:2] - target[:2]):.0f} mm apart in x-y")
