"""Sub-commands of `harness`, one module each (discovered by :mod:`harness.cli`)."""


def help_text(text: str) -> str:
    """``text`` for argparse, which %-formats help strings: a literal "%" (as in "30 %") is doubled."""
    return str(text).replace("%", "%%")
