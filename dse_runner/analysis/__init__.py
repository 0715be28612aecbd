"""dse-runner's analysis of results: diagnosis of what the model misses against its recordings."""
