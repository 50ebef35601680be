"""The reference pages of the documentation site, generated from the code: ``seaway docs reference``.

Each page is a pure function of what is installed (the commands' argument parsers, the key registry
and the access rules, the message types, the file types): no clock, no machine, no terminal width,
so the committed pages under ``docs/reference/`` can be compared with a fresh generation
(``tests/contract/test_docs_reference.py``).
"""
