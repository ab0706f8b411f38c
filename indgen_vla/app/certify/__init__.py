"""``indgen certify`` as a library: run the privileged oracle level by level (``run.certify``), over the built-in
jobs (``suite.certify_all``), with its live display (``display``); the certificates themselves are
``scenes.certificates``."""
