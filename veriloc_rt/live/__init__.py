"""The live view: a local web page on a running or finished run folder, and the config editor.

:mod:`.state` reads a run folder (``run.json``, the point-by-point ``<scenario>_results.csv``)
into the JSON the page polls; :mod:`.editor` turns the config schema into the editor's form and
checks a config with the package's own validation; :mod:`.server` serves both pages (static
files shipped in ``static/``) with the standard library's ``http.server`` on 127.0.0.1.
The view only reads the files a run writes: it never slows or changes the run.
"""
