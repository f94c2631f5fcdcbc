"""stageid.plants"""
