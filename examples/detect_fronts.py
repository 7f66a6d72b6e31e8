"""Find cabinet fronts in a rendered depth image with the FrontDetector.

The shipped ``cabinet.sdf`` (two doors over a drawer, its fronts facing +x) is rendered by a
640 x 480 depth camera 1.6 m in front of it (Drake's VTK renderer, no noise); the
``FrontDetector`` fits planes to the depth image and finds the rectangles on them (thesis
ch. 5). Each ``FrontRectangle`` has its centre and axes in the world frame (from the
camera's pose on the ``X_WC`` port) and its width and height in metres.

    python examples/detect_fronts.py
"""
import numpy as np
from pydrake.all import AbstractValue, AddMultibodyPlantSceneGraph, DiagramBuilder, Parser, \
    RigidTransform

from mmlearn.diagrams import AddDepthCamera, DepthCameraConfig, camera_pose_looking_at
from mmlearn.sdf import model_path
from mmlearn.systems import FrontDetector

builder = DiagramBuilder()
plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
Parser(plant).AddModels(str(model_path("cabinet.sdf")))
plant.Finalize()
camera = DepthCameraConfig()  # 640 x 480, 58 deg wide, like a Kinect
X_WC = camera_pose_looking_at(position=[1.6, 0.0, 1.2], target=[0.0, 0.0, 0.45])
sensor, _ = AddDepthCamera(builder, scene_graph, camera=camera, X_WC=X_WC, noise=None)
detector = builder.AddSystem(FrontDetector(intrinsics=camera.intrinsics(), seed=0))
builder.Connect(sensor.depth_image_32F_output_port(), detector.GetInputPort("depth_image"))
diagram = builder.Build()

context = diagram.CreateDefaultContext()
detector_context = detector.GetMyContextFromRoot(context)
detector.GetInputPort("X_WC").FixValue(detector_context, AbstractValue.Make(RigidTransform(X_WC)))
for r in detector.GetOutputPort("rectangles").Eval(detector_context):
    print(f"front at {np.round(r.center, 3)} m, {r.width:.3f} x {r.height:.3f} m")
