"""Behaviour trees as Nav2 writes them (BehaviorTree.CPP 4 XML): the tick engine, its nodes, the XML loader."""
