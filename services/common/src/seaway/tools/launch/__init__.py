"""``seaway launch PROFILE``: one command for the whole stack (profiles in ``deploy/profiles``)."""
