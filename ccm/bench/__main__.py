"""Entry point of ``make bench`` (``python -m ccm.bench``)."""

from ccm.bench.loop import main

raise SystemExit(main())
