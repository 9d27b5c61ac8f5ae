"""Console entry points: ``srcsctl`` (operator and integrator tool); ``srcsd``, ``srcs-sim``."""
