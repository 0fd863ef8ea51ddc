"""The InterDrive labeling tool: a web app for human annotators (docs/labeling.md)."""
