"""The application layer: CLI, engine, data regimes, real robot, BlockEnv; may import scenes and policies."""
