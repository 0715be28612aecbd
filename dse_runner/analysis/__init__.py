"""dse-runner's analysis of results: rankings, comparisons, diagnosis."""
