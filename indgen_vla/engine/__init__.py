"""The rollout engine: plan episodes, drive scenes with a policy, record every episode."""
