"""mmlearn.models."""
