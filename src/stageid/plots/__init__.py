"""stageid.plots"""
