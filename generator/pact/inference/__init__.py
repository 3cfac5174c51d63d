"""PAct as a generator: sampling from a photo (and part mask), the box layout fitted to the
mask, and the clean-up that turns samples into articulated objects (docs/pact.md)."""
