"""mmlearn.sdf."""
