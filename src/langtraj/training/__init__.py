"""Training LangTraj: turning InterDrive windows into model batches, and the sampling that balances them.

See docs/model.md.
"""
