"""``ccm suite``: a versioned benchmark of changing-contact tasks, one controller scored over
its tasks and seeds and ranked against the built-in controllers' stored results (issue #41,
part 3). The suites are ``configs/suite/*.yaml``; :mod:`ccm.suite.definition` reads them,
:mod:`ccm.suite.runner` runs an entry, :mod:`ccm.suite.board` ranks and
:mod:`ccm.suite.render` writes the leaderboard."""
