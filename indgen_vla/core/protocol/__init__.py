"""What a protocol is: the policy interface, axes and levels, the resolved plan, seeds, fingerprints."""
