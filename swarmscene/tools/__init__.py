"""Tools around runs: each is a command of its own.

    falsify.py   the falsifier: searches a scenario's parameters for a failure (``+sweep=falsify_*``)
    compile.py   ``swarmscene-compile``: every compiled kernel ahead, once per machine or image
    docgen.py    ``python -m swarmscene.tools.docgen``: the option tables of docs/ from the schema
    schema.py    ``python -m swarmscene.tools.schema``: the JSON schema of a scenario file
    info.py      ``swarmscene --version`` and ``swarmscene plugins``

Imports run one way: the command line imports this package; it imports the views, the run
directory's package, the composition and the engine, never the entry points.
"""
