"""What a person looks at: console tables, the Rerun recording, the certificate page."""
