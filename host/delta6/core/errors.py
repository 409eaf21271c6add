"""Errors that the command line reports as one line and exit status 2."""


class UserError(Exception):
    """Bad input from the user (a file, an argument, a port). The message names the problem."""

    exit_status = 2
