"""dse-runner's cases as plug-ins: the Robotti's field data and GPS objectives."""
