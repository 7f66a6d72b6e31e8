"""Models shared by several capabilities (SE(3) geometry, GP, file formats, cameras, marker sensing)."""

from mmlearn._lazy import lazy_exports

#: submodule -> the public names it defines (imported on first use)
_EXPORTS = {
    "camera": ["PinholeIntrinsics", "valid_depth_mask", "as_depth_image", "depth_to_points"],
    "depth_noise": ["DepthNoiseConfig", "apply_depth_noise", "predicted_depth_std", "incidence_cosine", "projector_shadow"],
    "fileio": ["atomic_write_text"],
    "gp": ["GaussianProcess"],
    "marker_detection": ["DepthMirrorTest", "DetectorConfig", "MarkerDetections", "detect_marker_poses", "make_detector", "mirror_test_from_depth"],
    "sdf_writer": ["SdfModel", "Link", "Box", "Cylinder", "Sphere", "Capsule", "Mesh", "JOINT_TYPES", "box_inertia", "cylinder_inertia"],
    "se3": ["PoseArray", "as_pose_array", "to_xyzquat", "to_matrices", "relative_poses", "rotation_angle", "rotation_distance", "matrix_to_pose7", "pose7_to_matrix", "quat_distance", "project_to_so3", "rotvec_to_matrix", "matrix_to_rotvec"],
    "track_io": ["Track", "TrackFileError", "read_track", "find_track_files"],
}

__all__ = [
    "apply_depth_noise",
    "as_depth_image",
    "as_pose_array",
    "atomic_write_text",
    "Box",
    "box_inertia",
    "Capsule",
    "Cylinder",
    "cylinder_inertia",
    "depth_to_points",
    "DepthMirrorTest",
    "DepthNoiseConfig",
    "detect_marker_poses",
    "DetectorConfig",
    "find_track_files",
    "GaussianProcess",
    "incidence_cosine",
    "JOINT_TYPES",
    "Link",
    "make_detector",
    "MarkerDetections",
    "matrix_to_pose7",
    "matrix_to_rotvec",
    "Mesh",
    "mirror_test_from_depth",
    "PinholeIntrinsics",
    "pose7_to_matrix",
    "PoseArray",
    "predicted_depth_std",
    "project_to_so3",
    "projector_shadow",
    "quat_distance",
    "read_track",
    "relative_poses",
    "rotation_angle",
    "rotation_distance",
    "rotvec_to_matrix",
    "SdfModel",
    "Sphere",
    "to_matrices",
    "to_xyzquat",
    "Track",
    "TrackFileError",
    "valid_depth_mask",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
