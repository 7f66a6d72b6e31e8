"""mmlearn.systems."""
