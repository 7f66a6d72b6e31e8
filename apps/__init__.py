"""mmlearn.apps."""
