"""``wet-eha-thermal play``: a bag on the ROS graph with /clock (the player parses its options)."""

from typing import List

HELP = ('publish a bag on the ROS graph with /clock (wet-eha-thermal play BAG [--rate R] '
        '[--loop] ...; play --help for all options)')
DESCRIPTION = None
#: The player parses its own command line: main() hands it everything after 'play'.
OWN_PARSER = True


def main(argv: List[str]) -> int:
    """Run the player on ``argv`` (what follows ``play``)."""
    from ..ros import player

    return player.main(argv)
