"""What the tests share besides fixtures (conftest.py): real clusters, browsers, plug-ins and
cases, imported as ``support.<name>`` (tests/ is on the path), apart from the tests themselves
and from the package's modules."""
