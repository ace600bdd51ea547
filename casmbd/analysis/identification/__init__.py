"""Dynamic parameter identification: the regressor, base parameters, estimation."""
