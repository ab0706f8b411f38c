"""indgen inside LeRobot's tools and LeRobot's results inside indgen (docs/lerobot.md): the ``--env.type=indgen`` env
(``level_env``, ``env_config``), ``indgen import lerobot-eval`` (``eval_import``) and the level ladder run through
``lerobot-eval`` (``ladder``)."""
