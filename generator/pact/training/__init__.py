"""Training PAct: data pipelines over dataset folders, augmentation, and the training entry
points of stage 1, stage 2 and the foreground net (docs/pact.md)."""
