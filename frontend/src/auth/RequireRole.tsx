import type { ReactNode } from "react";
import { Navigate, useLocation } from "react-router-dom";
import { mayOpen, type SECTION_ROLES } from "../lib/roles";
import { NotHerePage } from "../pages/NotHerePage";
import { useAuth } from "./AuthContext";

export function RequireRole({
  section,
  children,
}: {
  section: keyof typeof SECTION_ROLES;
  children: ReactNode;
}) {
  const { user } = useAuth();
  const location = useLocation();
  if (!user) return <Navigate to="/login" replace state={{ from: location.pathname }} />;
  if (!mayOpen(user.role, section)) return <NotHerePage kind="forbidden" />;
  return <>{children}</>;
}
