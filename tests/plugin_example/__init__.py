"""A plugin as a third-party package would write it (a toy prior, a toy likelihood and a toy mocap reader in
:mod:`.toy_plugin`), with its own tests inheriting the toolkit's contract tests (:mod:`.test_toy_plugin`)."""
