"""mmlearn.diagrams."""
