"""The sandbox's own tests: its protocol, limits, cache, seccomp filter and attack suite.

They run from a checkout of the repository that holds the package (the test command collects
``reference_impl``), never from an installed wheel (which leaves them out). The package these tests
expose in their sandboxes is the repository's library, ``flowtrack``; any package would do.
"""
