"""Pure statistics of episode tables: rates and CIs, k*, sequential tests, paired contrasts."""
