"""stageid.subspace"""
