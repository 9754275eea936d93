// Keeps envkit_toolcommon non-empty before any shared tool code exists.
