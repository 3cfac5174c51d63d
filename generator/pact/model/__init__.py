"""The PAct networks: encoders, VAEs, flow transformers, the articulation head, their
configurations and checkpoints (docs/pact.md)."""
