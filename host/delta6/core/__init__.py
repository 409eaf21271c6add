"""The reference model: the paper's equations, design files, workspace, the design report,
Table V percentiles, history operators, paths and errors. Imports nothing else of delta6."""
