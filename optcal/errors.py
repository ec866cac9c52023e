"""Errors a user can fix. The CLI turns these into one line on stderr and exit status 2."""


class InputError(ValueError):
    """Bad input (data, options, names): the message names the problem and the fix, in one line."""


class BudgetExhausted(Exception):
    """Raised by a problem when its evaluation, time or target budget is used up."""
