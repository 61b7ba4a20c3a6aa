"""The result contract: the document written, its checks when read back, and its exports."""
