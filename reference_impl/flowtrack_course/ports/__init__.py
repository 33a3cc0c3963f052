"""Cross-language ports checked against shared test vectors made by the reference.

``vectors`` writes ``cpp_java_matlab_ports/vectors/<problem>.json``; each ``lang_*`` module builds
and runs one language's harness on those files; ``runner`` prints the table and is the
``flowtrack ports`` command.
"""
