"""Reports for people: the self-contained HTML page of a pipeline run."""
