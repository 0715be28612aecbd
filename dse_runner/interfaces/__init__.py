"""dse-runner's what users touch: the command, the dashboard, the report, figures."""
