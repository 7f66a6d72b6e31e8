"""Read a TactileSensor while a gripper squeezes a block (thesis ch. 6-7).

``MakeTactileGraspDiagram`` builds a parallel two-finger gripper with compliant
(hydroelastic) pads, each carrying a 5 x 3 taxel array like the PR2's, the switching
controller of Eq. 7.8 (close at constant speed until a pad feels 1 N, then rise to
``f_target`` N per finger, hold, release) and a ``TactileSensor``: the contact pressure
integrated over each cell, normalised to [0, 1] at saturation, 25 Hz. Here it closes on a
rigid 7 x 10 x 12 cm block; we read the sensor's ports mid-hold.

    python examples/tactile_grasp.py
"""
import numpy as np
from pydrake.all import Simulator

from mmlearn.diagrams import MakeTactileGraspDiagram, TactileGraspConfig
from mmlearn.sdf.tactile import block_sdf

config = TactileGraspConfig(pad="pr2", f_target=10.0, seed=0)
diagram, parts = MakeTactileGraspDiagram(config, object_sdf=block_sdf((0.07, 0.1, 0.12)))
simulator = Simulator(diagram)
simulator.AdvanceTo(1.6)  # contact at ~1.1 s, holding at f_target until ~1.9 s

sensor = parts["sensor"]  # the TactileSensor
context = sensor.GetMyContextFromRoot(simulator.get_context())
pad_force = sensor.GetOutputPort("pad_force").Eval(context)
images = sensor.split(sensor.GetOutputPort("taxels").Eval(context)[None, :])
print(f"pad forces {np.round(pad_force, 2)} N (target {config.f_target} N per finger)")
for name, image in images.items():
    print(f"{name} pad readings (row 0 at the fingertip):\n{np.round(image[0], 2)}")
