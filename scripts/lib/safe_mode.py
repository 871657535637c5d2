"""The runs of safe-mode rows in a run's `command_status` column (scripts/pil.sh's reset and
watchdog tests): a row's status is 0 fresh, 1 held, 2 safe mode."""


def runs(status):
    """Each run of consecutive safe-mode rows (status 2) as (length, first row), in order."""
    found, start = [], None
    for i, x in enumerate(list(status) + [0]):
        if x == 2 and start is None:
            start = i
        elif x != 2 and start is not None:
            found.append((i - start, start))
            start = None
    return found
