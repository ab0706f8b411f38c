"""Run directories on disk: manifest, episodes.parquet, shards, videos, redaction of secrets."""
