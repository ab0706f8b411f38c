"""``indgen certify`` as a library: its config (``certify_config.CertifyConfig``), the privileged oracle run level
by level (``certify_levels.certify``), over many pairs in one pool (``batch``) or the built-in jobs
(``suite.certify_all``), with its live display (``display``); the certificates themselves are
``scenes.certificates``."""
