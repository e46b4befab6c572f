import { NavLink, Outlet } from "react-router-dom";

/** Engineering workspace: registry, fleet and deployments, jobs. */
export function EngineerLayout() {
  return (
    <main className="page">
      <nav className="subnav" aria-label="Engineering">
        <NavLink to="/engineer" end>Model registry</NavLink>
        <NavLink to="/engineer/fleet">Fleet &amp; deployments</NavLink>
        <NavLink to="/engineer/jobs">Jobs</NavLink>
      </nav>
      <Outlet />
    </main>
  );
}
